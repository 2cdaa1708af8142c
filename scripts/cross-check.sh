#!/usr/bin/env bash
# Runs a cross-built binary (scripts/release.sh) under qemu-user and holds it to x86_64's
# bytes: every golden output in tests/golden/ byte for byte, then scripts/compare-binaries.sh
# (the README's commands and a set over every method, format, colour mode, preset, CMYK
# plates and batch) against the x86_64 release binary.
#
# Usage: scripts/cross-check.sh [--goldens] TRIPLE [REFERENCE_BINARY]
#        scripts/cross-check.sh --wheel WHEEL [REFERENCE_BINARY] [-- PYTEST_ARGS...]
#   --goldens: the golden outputs only (what CI runs: scripts/release.sh --ci)
#   TRIPLE: aarch64-unknown-linux-musl, aarch64-unknown-linux-gnu (its glibc: QEMU_LD_PREFIX,
#   default /usr/aarch64-linux-gnu from Debian's libc6-arm64-cross),
#   armv7-unknown-linux-gnueabihf (QEMU_LD_PREFIX, default /usr/arm-linux-gnueabihf from
#   libc6-armhf-cross, or Debian's libc6:armhf unpacked), or x86_64-unknown-linux-musl
#   REFERENCE_BINARY: default the x86_64-unknown-linux-musl binary release.sh built
#   --wheel: installs an aarch64 or armv7l wheel (scripts/release.sh) into Debian bookworm's
#   CPython 3.11 for that architecture and runs the Python package's tests (python/tests)
#   under qemu-user, child interpreters included (HALFTONE_PYTHON_LAUNCHER). Byte identity
#   is with REFERENCE_BINARY, default the x86_64 release binary (target/release/halftone).
#   The CPython is a sysroot of Debian's debs (python3.11-minimal, its libraries,
#   python3-numpy, python3-pil), `apt-get download`ed and unpacked with `dpkg-deb -x` into
#   HALFTONE_PYTHON_ROOT (default target/cross/python-ARCH; made when missing; needs
#   `dpkg --add-architecture ARCH && apt-get update`). pytest comes from PyPI (pure Python,
#   into target/cross/python-pytest). A PYTHONPATH that is set comes before the sysroot's
#   packages (e.g. a folder with PyPI's numpy and Pillow for that platform).
# Needs Debian's qemu-user (qemu-aarch64, qemu-arm). Exits 1 on any difference.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

if [ "${1:-}" = "--wheel" ]; then
  wheel=$(realpath "${2:?usage: scripts/cross-check.sh --wheel WHEEL [REFERENCE_BINARY] [-- PYTEST_ARGS...]}")
  shift 2
  ref=${CARGO_TARGET_DIR:-$root/target}/release/halftone
  if [ $# -gt 0 ] && [ "$1" != "--" ]; then
    ref=$(realpath "$1")
    shift
  fi
  [ "${1:-}" = "--" ] && shift
  case $wheel in
    *_aarch64.whl) arch=arm64 runner=qemu-aarch64 ;;
    *_armv7l.whl) arch=armhf runner=qemu-arm ;;
    *) echo "cross-check: $wheel: not an aarch64 or armv7l wheel" >&2; exit 1 ;;
  esac
  [ -f "$wheel" ] || { echo "cross-check: $wheel: no such wheel" >&2; exit 1; }
  [ -x "$ref" ] || { echo "cross-check: $ref: no reference binary (cargo build --release)" >&2; exit 1; }
  command -v "$runner" >/dev/null || { echo "cross-check: $runner not found (apt-get install qemu-user)" >&2; exit 1; }
  cross=${CARGO_TARGET_DIR:-$root/target}/cross
  pyroot=${HALFTONE_PYTHON_ROOT:-$cross/python-$arch}
  if [ ! -x "$pyroot/usr/bin/python3.11" ]; then
    dpkg --print-foreign-architectures | grep -qx "$arch" || {
      echo "cross-check: no $arch packages (dpkg --add-architecture $arch && apt-get update)" >&2
      exit 1
    }
    echo "cross-check: making $pyroot from Debian's $arch packages"
    debs=$(mktemp -d)
    names="python3.11-minimal libpython3.11-minimal libpython3.11-stdlib libc6 libgcc-s1
      libstdc++6 zlib1g libbz2-1.0 liblzma5 libexpat1 libffi8 libssl3 libcrypt1 libuuid1
      libsqlite3-0 libreadline8 libncursesw6 libtinfo6 libdb5.3 libnsl2 libtirpc3 libgssapi-krb5-2
      libkrb5-3 libk5crypto3 libkrb5support0 libcom-err2 libkeyutils1
      python3-numpy libblas3 liblapack3 libgfortran5
      python3-pil libjpeg62-turbo libtiff6 libwebp7 libwebpdemux2 libwebpmux3 libopenjp2-7
      libimagequant0 liblcms2-2 libfreetype6 libpng16-16 libbrotli1 libraqm0 libfribidi0
      libharfbuzz0b libglib2.0-0 libgraphite2-3 libpcre2-8-0 libxcb1 libxau6 libxdmcp6 libbsd0
      libmd0 libdeflate0 libjbig0 liblerc4 libzstd1 libgomp1"
    # shellcheck disable=SC2046
    (cd "$debs" && apt-get download -q -o APT::Sandbox::User=root $(printf '%s:'"$arch"' ' $names) >/dev/null)
    mkdir -p "$pyroot"
    for d in "$debs"/*.deb; do dpkg-deb -x "$d" "$pyroot"; done
    rm -rf "$debs"
    # BLAS and LAPACK are Debian alternatives (links made by the package scripts).
    multiarch=$(find "$pyroot/usr/lib" -path '*/blas/libblas.so.3' | head -n 1 | xargs dirname | xargs dirname)
    ln -sf blas/libblas.so.3 "$multiarch/libblas.so.3"
    ln -sf lapack/liblapack.so.3 "$multiarch/liblapack.so.3"
  fi
  pytest_dir=$cross/python-pytest
  if [ ! -d "$pytest_dir/pytest" ]; then
    python3 -m pip install -q --target "$pytest_dir" "pytest>=7"
  fi
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
  # A wheel is a zip of the folders to import from (an abi3 wheel: no per-version names).
  python3 -m zipfile -e "$wheel" "$work/site"
  launcher="$runner -L $pyroot"
  echo "cross-check: $(basename "$wheel") in $arch CPython 3.11 under $runner, against $ref"
  # From outside the source tree, so the wheel's halftone is imported, not python/halftone.
  cd "$work"
  PYTHONPATH="$work/site:$pytest_dir${PYTHONPATH:+:$PYTHONPATH}" CI="${CI:-true}" \
    HALFTONE_CLI="$ref" HALFTONE_PYTHON_LAUNCHER="$launcher" \
    $launcher "$pyroot/usr/bin/python3.11" -m pytest -q -p no:cacheprovider "$root/python/tests" "$@"
  exit
fi
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
