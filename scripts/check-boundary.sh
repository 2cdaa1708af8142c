#!/usr/bin/env bash
# The core library's boundary: built without the command line, it depends on none of the
# CLI's crates, and nothing in it exits the process, installs a signal handler or keeps
# mutable global state.
#
# Usage: scripts/check-boundary.sh [--build]   (--build: `cargo build`, else `cargo check`)
# Prints what it checked and a closing `N passed, M failed`; exits 1 on a failure.
set -uo pipefail
cd "$(dirname "$0")/.."
pass=0
fail=0
ok() { echo "ok: $1"; pass=$((pass + 1)); }
bad() { echo "FAILED: $1"; fail=$((fail + 1)); }

verb=check
[ "${1:-}" = "--build" ] && verb=build
if cargo "$verb" -q --lib --no-default-features 2>/tmp/boundary.$$; then
  ok "cargo $verb --lib --no-default-features"
else
  bad "cargo $verb --lib --no-default-features: $(tail -5 /tmp/boundary.$$)"
fi
rm -f /tmp/boundary.$$

tree=$(cargo tree -e normal --no-default-features --prefix none 2>/dev/null | awk '{print $1}' | sort -u)
for c in clap indicatif plotters ab_glyph signal-hook lcms2 lcms2-sys ctrlc anyhow clap_complete clap_mangen; do
  if grep -qx "$c" <<<"$tree"; then
    bad "the core library depends on $c"
  else
    ok "no $c in the core library's tree"
  fi
done

# Library sources: everything but the binary (src/main.rs, src/cli/). An item behind
# `#[cfg(feature = "cli")]` or `"lab"` (the line before it, or a gated `mod`) belongs to the
# command line or the measuring tools, neither in the core library.
lib_files=$(find src -name '*.rs' ! -path 'src/cli/*' ! -name main.rs | sort)
ungated() {
  # Lines matching $1 whose previous non-blank line is not a cfg(feature = "cli") gate and
  # that are not in a test module (a crude but honest textual check).
  # A gated `mod … {` is skipped to its closing brace at the same indentation.
  awk -v pat="$1" '
    FNR == 1 { gated = 0; intest = 0; skipping = 0 }
    skipping { if ($0 == closing) skipping = 0; next }
    /^#\[cfg\(test\)\]/ { intest = 1 }
    gated && /^[[:space:]]*(pub )?mod [a-z_]+ \{/ { match($0, /^[[:space:]]*/); closing = substr($0, 1, RLENGTH) "}"; skipping = 1; next }
    $0 ~ pat && !gated && !intest && $0 !~ /^[[:space:]]*\/\// { print FILENAME ":" FNR ": " $0 }
    /^[[:space:]]*#\[cfg\(feature = "(cli|lab)"\)\]/ { gated = 2 }
    { if (gated > 0) gated-- }
  ' $lib_files
}
hits=$(ungated 'process::exit|signal_hook|ctrlc::|libc::signal|sigaction') || hits="(the scan failed)"
[ -z "$hits" ] && ok "no process exit or signal handler in the library" || bad "process or signal calls: $hits"
hits=$(ungated '^[[:space:]]*(pub )?static (mut )?[A-Z_]+: *(std::sync::)?(atomic::)?(Mutex|RwLock|Atomic[A-Za-z0-9]+|Cell|RefCell)') || hits="(the scan failed)"
[ -z "$hits" ] && ok "no mutable global state in the library outside the cli and lab features" || bad "mutable statics: $hits"
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
