#!/usr/bin/env bash
# Runs a cross-built binary (scripts/release.sh) under qemu-user and holds it to x86_64's
# bytes: every golden output in tests/golden/ byte for byte, then scripts/compare-binaries.sh
# (the README's commands and a set over every method, format, colour mode, preset, CMYK
# plates and batch) against the x86_64 release binary.
#
# Usage: scripts/cross-check.sh [--goldens] TRIPLE [REFERENCE_BINARY]
#   --goldens: the golden outputs only (what CI runs: scripts/release.sh --ci)
#   TRIPLE: aarch64-unknown-linux-musl, aarch64-unknown-linux-gnu (its glibc: QEMU_LD_PREFIX,
#   default /usr/aarch64-linux-gnu from Debian's libc6-arm64-cross),
#   armv7-unknown-linux-gnueabihf (QEMU_LD_PREFIX, default /usr/arm-linux-gnueabihf from
#   libc6-armhf-cross, or Debian's libc6:armhf unpacked), or x86_64-unknown-linux-musl
#   REFERENCE_BINARY: default the x86_64-unknown-linux-musl binary release.sh built
# Needs Debian's qemu-user (qemu-aarch64, qemu-arm). Exits 1 on any difference.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
goldens_only=false
if [ "${1:-}" = "--goldens" ]; then
  goldens_only=true
  shift
fi
triple=${1:?usage: scripts/cross-check.sh TRIPLE [REFERENCE_BINARY]}
cross=${CARGO_TARGET_DIR:-$root/target}/cross
profile=${HALFTONE_PROFILE:-dist}
bin=$cross/$triple/$triple/$profile/halftone
ref=${2:-$cross/x86_64-unknown-linux-musl/x86_64-unknown-linux-musl/$profile/halftone}
[ -x "$bin" ] || { echo "cross-check: $bin: not built (scripts/release.sh $triple)" >&2; exit 1; }
$goldens_only || [ -x "$ref" ] || { echo "cross-check: $ref: not built (scripts/release.sh x86_64-unknown-linux-musl)" >&2; exit 1; }
case $triple in
  aarch64-*) runner=(qemu-aarch64) sysroot=/usr/aarch64-linux-gnu deb=libc6-arm64-cross ;;
  armv7-*) runner=(qemu-arm) sysroot=/usr/arm-linux-gnueabihf deb=libc6-armhf-cross ;;
  x86_64-*) runner=() sysroot=/ deb=libc6 ;;
  *) echo "cross-check: no runner for $triple" >&2; exit 1 ;;
esac
if [ ${#runner[@]} -gt 0 ] && ! command -v "${runner[0]}" >/dev/null; then
  echo "cross-check: ${runner[0]} not found (apt-get install qemu-user)" >&2
  exit 1
fi
# A glibc build needs the target's dynamic loader and libc: qemu-user finds them under
# QEMU_LD_PREFIX (musl builds are static and need none).
case $triple in
  *-gnu*)
    export QEMU_LD_PREFIX=${QEMU_LD_PREFIX:-$sysroot}
    [ -d "$QEMU_LD_PREFIX/lib" ] || {
      echo "cross-check: $QEMU_LD_PREFIX/lib: no $triple glibc (apt-get install $deb, or set QEMU_LD_PREFIX)" >&2
      exit 1
    }
    ;;
esac
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# A wrapper that compare-binaries.sh runs as if it were the binary.
printf '#!/bin/sh\nexec %s "%s" "$@"\n' "${runner[*]}" "$bin" >"$work/halftone-$triple"
chmod +x "$work/halftone-$triple"
"$work/halftone-$triple" --version

pass=0
fail=0
while read -r name input ext args; do
  case $name in '#'* | '') continue ;; esac
  out=$work/$name.$ext
  # shellcheck disable=SC2086
  if "$work/halftone-$triple" convert "tests/golden/inputs/$input" -o "$out" $args 2>"$work/err" \
    && cmp -s "$out" "tests/golden/out/$name.$ext"; then
    pass=$((pass + 1))
  else
    echo "golden DIFFERENT: $name ($(head -c 200 "$work/err"))"
    fail=$((fail + 1))
  fi
done <tests/golden/cases.txt
echo "golden: $pass passed, $fail failed ($triple)"
[ "$fail" -eq 0 ]
$goldens_only && exit 0
bash scripts/compare-binaries.sh "$ref" "$work/halftone-$triple" | tail -n 1
