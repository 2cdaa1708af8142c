#!/usr/bin/env bash
# The Python package's CI: a fresh venv, a wheel built with maturin, installed, and the
# pytest suite (byte identity with the command line, bad input, the examples) run against
# it. Any failure fails the script; a run that collects no tests (pytest exit 5) fails too.
# Needs the command line built first (cargo build --release) for the byte-identity tests.
#
# HALFTONE_WHEEL=FILE tests that wheel instead of building one (CI: the x86_64 wheel
# scripts/release.sh --ci built), installed and tested on a PATH without cargo or rustc,
# as on a machine with no Rust toolchain.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(dirname "$here")"
python="${PYTHON:-python3}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

"$python" -m venv "$work/venv"
venv="$work/venv/bin"
"$venv/pip" install --quiet --upgrade pip
if [ -n "${HALFTONE_WHEEL:-}" ]; then
    [ -f "$HALFTONE_WHEEL" ] || { echo "python/ci.sh: $HALFTONE_WHEEL: no such wheel" >&2; exit 1; }
    # PATH without the folders that hold cargo or rustc.
    clean=""
    IFS=: read -r -a dirs <<<"$PATH"
    for d in "${dirs[@]}"; do
        [ -e "$d/cargo" ] || [ -e "$d/rustc" ] || clean="${clean:+$clean:}$d"
    done
    export PATH="$clean"
    if command -v cargo >/dev/null || command -v rustc >/dev/null; then
        echo "python/ci.sh: cargo or rustc still on PATH" >&2
        exit 1
    fi
    echo "python/ci.sh: installing $(basename "$HALFTONE_WHEEL") with no cargo or rustc on PATH"
    "$venv/pip" install --quiet --only-binary halftone pytest numpy Pillow "$HALFTONE_WHEEL"
else
    "$venv/pip" install --quiet "maturin>=1.16,<2" pytest numpy Pillow
    # The wheel: abi3 (one wheel for every CPython from 3.9).
    (cd "$here" && "$venv/maturin" build --release --out "$work/wheels" --interpreter "$venv/python")
    ls "$work/wheels"
    "$venv/pip" install --quiet "$work"/wheels/halftone-*.whl
fi

cli="${HALFTONE_CLI:-$repo/target/release/halftone}"
if [ ! -x "$cli" ]; then
    echo "python/ci.sh: $cli is missing: run cargo build --release first" >&2
    exit 1
fi
# Run from outside the source tree so the installed wheel is imported, not python/halftone.
cd "$work"
set +e
CI="${CI:-true}" HALFTONE_CLI="$cli" "$venv/python" -m pytest -q -p no:cacheprovider "$here/tests"
status=$?
set -e
if [ "$status" -ne 0 ]; then
    echo "python/ci.sh: pytest failed (exit $status)" >&2
    exit 1
fi
echo "python/ci.sh: all Python tests passed"
