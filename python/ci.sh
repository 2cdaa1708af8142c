#!/usr/bin/env bash
# The Python package's CI: a fresh venv, a wheel built with maturin, installed, and the
# pytest suite (byte identity with the command line, bad input, the examples) run against
# it. Any failure fails the script; a run that collects no tests (pytest exit 5) fails too.
# Needs the command line built first (cargo build --release) for the byte-identity tests.
#
# The wheel is installed on a PATH without cargo or rustc, as on a machine with no Rust
# toolchain. HALFTONE_WHEEL=FILE tests that wheel instead of building one (a wheel that
# scripts/release.sh built).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(dirname "$here")"
python="${PYTHON:-python3}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

cli="${HALFTONE_CLI:-$repo/target/release/halftone}"
if [ ! -x "$cli" ]; then
    echo "python/ci.sh: $cli is missing: run cargo build --release first" >&2
    exit 1
fi

"$python" -m venv "$work/venv"
venv="$work/venv/bin"
"$venv/pip" install --quiet --upgrade pip
if [ -z "${HALFTONE_WHEEL:-}" ]; then
    # The wheel: abi3 (one wheel for every CPython from 3.9), built here with the toolchain.
    "$venv/pip" install --quiet "maturin>=1.16,<2"
    # The type stub, from the option table (not kept in git).
    "$python" "$here/stub.py" "$cli"
    (cd "$here" && "$venv/maturin" build --release --out "$work/wheels" --interpreter "$venv/python")
    HALFTONE_WHEEL="$(ls "$work"/wheels/halftone-*.whl)"
fi
[ -f "$HALFTONE_WHEEL" ] || { echo "python/ci.sh: $HALFTONE_WHEEL: no such wheel" >&2; exit 1; }
# Installed and tested on a PATH without the folders that hold cargo or rustc, as on a
# machine with no Rust toolchain (a wheel that needed one to install would fail here).
clean=""
IFS=: read -r -a dirs <<<"$PATH"
for d in "${dirs[@]}"; do
    [ -e "$d/cargo" ] || [ -e "$d/rustc" ] || clean="${clean:+$clean:}$d"
done
if PATH="$clean" command -v cargo >/dev/null || PATH="$clean" command -v rustc >/dev/null; then
    echo "python/ci.sh: cargo or rustc still on PATH" >&2
    exit 1
fi
echo "python/ci.sh: installing $(basename "$HALFTONE_WHEEL") with no cargo or rustc on PATH"
PATH="$clean" "$venv/pip" install --quiet --only-binary halftone pytest numpy Pillow "$HALFTONE_WHEEL"

# Run from outside the source tree so the installed wheel is imported, not python/halftone.
cd "$work"
set +e
PATH="$clean" CI="${CI:-true}" HALFTONE_CLI="$cli" "$venv/python" -m pytest -q -p no:cacheprovider "$here/tests"
status=$?
set -e
if [ "$status" -ne 0 ]; then
    echo "python/ci.sh: pytest failed (exit $status)" >&2
    exit 1
fi
echo "python/ci.sh: all Python tests passed"
