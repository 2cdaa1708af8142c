#!/usr/bin/env bash
# Runs every fuzz target in turn (cargo-fuzz, libFuzzer) on the stable toolchain.
#
#   scripts/fuzz.sh               # every target, 60 s each
#   scripts/fuzz.sh 600           # every target, 10 minutes each
#   scripts/fuzz.sh 300 read_png  # some targets
#   ASAN=1 scripts/fuzz.sh 60     # with AddressSanitizer (RUSTC_BOOTSTRAP=1; slower, for unsafe code)
#
# Needs `cargo install cargo-fuzz` (about 80 s) and a C++ compiler (libFuzzer). Without a
# sanitizer (`-s none`), libFuzzer only sees comparisons of magic bytes with the LLVM flag
# below. The committed seeds are fuzz/corpus/TARGET/; what a run learns goes to
# fuzz/work/TARGET/ (not committed; kept between runs); findings to fuzz/artifacts/TARGET/.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
secs=${1:-60}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  mapfile -t targets < <(cargo fuzz list)
fi
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$PWD/target}
if [ "${ASAN:-0}" = 1 ]; then
  export RUSTC_BOOTSTRAP=1
  sanitizer=(-s address)
else
  export RUSTFLAGS="${RUSTFLAGS:-} -Cllvm-args=-max-loads-per-memcmp=0"
  sanitizer=(-s none)
fi
# Limits every run shares: 2 GiB of memory (the decoders are capped far below that), 10 s
# for one input, inputs up to 256 KiB.
flags=(-rss_limit_mb=2048 -timeout=10 -max_len=262144 -print_final_stats=1)
status=0
for t in "${targets[@]}"; do
  echo "== $t ($secs s)"
  mkdir -p "corpus/$t" "work/$t" "artifacts/$t"
  if ! cargo fuzz run "${sanitizer[@]}" "$t" "work/$t" "corpus/$t" -- \
      -max_total_time="$secs" -artifact_prefix="artifacts/$t/" "${flags[@]}" 2>&1 |
      tee "artifacts/$t/last-run.log" | grep -E '^(#[0-9]+.*DONE|==|stat::|SUMMARY|Done)|panicked|ERROR'; then
    :
  fi
  if grep -qE 'SUMMARY|panicked|ERROR: libFuzzer' "artifacts/$t/last-run.log"; then
    echo "!! $t: finding, see fuzz/artifacts/$t/"
    status=1
  fi
done
exit $status
