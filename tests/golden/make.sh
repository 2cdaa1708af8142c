#!/usr/bin/env bash
# Regenerates tests/golden/out/ with the binary given (default: target/debug/halftone).
# Only for a deliberate change of output bytes: the files are the reference the streaming
# pipeline is held to.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
bin=${1:-${CARGO_TARGET_DIR:-target}/debug/halftone}
mkdir -p "$here/out"
grep -v '^#' "$here/cases.txt" | while read -r name input ext args; do
    # shellcheck disable=SC2086
    "$bin" convert "$here/inputs/$input" -o "$here/out/$name.$ext" $args
done
