#!/usr/bin/env bash
# Builds into target/dist/ everything a release ships, then lists each artefact's size and
# writes SHA256SUMS over them:
#   - the command line as a static Linux binary for each target, with its man pages and shell
#     completions, in halftone-VERSION-TRIPLE.tar.gz;
#   - the Python package: an abi3 wheel for each target (manylinux 2.17, which auditwheel
#     accepts) and an sdist that builds with a Rust toolchain;
#   - the WebAssembly build as an npm package (halftone-web-VERSION.tgz, `npm pack` of web/);
#   - the crate for the registry: `cargo package` (which builds it from the package alone),
#     `cargo publish --dry-run` and the .crate file.
#
# Usage: scripts/release.sh [--ci] [TARGET...]
#   default targets: x86_64-unknown-linux-musl aarch64-unknown-linux-musl
#                    armv7-unknown-linux-gnueabihf.2.17
#   --ci: what CI runs (.ci/run), at the least build time that still proves the release
#     route: the x86_64 binary and wheel come from the native builds CI makes anyway (the
#     binary `cargo build --release` built and the tests ran, packaged; the wheel built with
#     maturin natively, as python/ci.sh did, manylinux tag from this machine's glibc), and one
#     cross target, default aarch64-unknown-linux-gnu.2.17, whose binary and wheel share one
#     build folder and its dependency builds (release profile; glibc 2.17 like the wheels, so
#     Zig builds no musl libc). No sdist, no crate. Then the checks: the aarch64 binary
#     under qemu-user gives every golden output byte for byte (scripts/cross-check.sh
#     --goldens; its glibc from Debian's libc6-arm64-cross), and the npm tarball installed
#     into an empty folder converts pictures in Node to the x86_64 binary's bytes
#     (web/test/node-package.mjs). The x86_64 wheel is then tested by python/ci.sh
#     (HALFTONE_WHEEL=target/dist/halftone-…x86_64.whl), on a PATH without cargo or rustc.
#     Exits 1 on any failure.
#
# Cross-building: cargo-zigbuild and maturin --zig with Zig as the C compiler and linker,
# all from PyPI (installed into target/zig-venv when missing), so one machine with a Rust
# toolchain and registry access builds every target; no Debian cross toolchain or sysroot
# is needed. x86_64 and aarch64 binaries are musl, fully static (any Linux from 2.6.39 on,
# any libc). armv7 is glibc 2.17 or later (dynamic), because the toolchain's registry here
# serves no armv7 musl standard library. Wheels are glibc (manylinux_2_17: what pip on
# Raspberry Pi OS, Debian or Ubuntu takes). JPEG goes through the image crate on every
# target (no system libjpeg to link statically: HALFTONE_NO_LIBJPEG=1), so every target
# gives the same bytes; scripts/cross-check.sh runs the ARM binaries under qemu-user.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
start=$SECONDS
ci=false
if [ "${1:-}" = "--ci" ]; then
  ci=true
  shift
fi
version=$(awk -F'"' '/^version = / { print $2; exit }' Cargo.toml)
dist=$root/target/dist
# One build folder a target (binaries and wheels alike): builds of different targets share
# nothing, and separate folders let them run at once (by hand) without waiting on a lock.
cross=${CARGO_TARGET_DIR:-$root/target}/cross
# The `dist` profile (thin LTO) for what ships; HALFTONE_PROFILE=release for a quicker build
# (the default with --ci: the same code, no LTO).
if $ci; then profile=${HALFTONE_PROFILE:-release}; else profile=${HALFTONE_PROFILE:-dist}; fi
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  if $ci; then
    targets=(aarch64-unknown-linux-gnu.2.17)
  else
    targets=(x86_64-unknown-linux-musl aarch64-unknown-linux-musl armv7-unknown-linux-gnueabihf.2.17)
  fi
fi
# With --ci, the x86_64 pieces are this machine's native builds (see the usage above).
host_triple=$(rustc -vV | sed -n 's/^host: //p')
die() {
  echo "release: $*" >&2
  exit 1
}

for f in python/pyproject.toml python/Cargo.toml web/Cargo.toml web/package.json; do
  grep -q "^ *\"\?version\"\? *[=:] *\"$version\"" "$f" || die "$f: version is not $version (Cargo.toml)"
done

venv=$root/target/zig-venv
if [ ! -x "$venv/bin/cargo-zigbuild" ] || [ ! -x "$venv/bin/maturin" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q ziglang==0.17.1 cargo-zigbuild==0.24.1 "maturin>=1.16,<2" auditwheel
fi
export PATH="$venv/bin:$PATH"

mkdir -p "$dist"
rm -f "$dist/SHA256SUMS" "$dist"/halftone-*

# ---- The command line ------------------------------------------------------------------
host_bin=""
for t in "${targets[@]}"; do
  triple=${t%%.2.*}                      # armv7-unknown-linux-gnueabihf.2.17 -> the triple
  rustup target add "$triple" >/dev/null
  echo "release: building the binary for $t ($profile)"
  step=$SECONDS
  HALFTONE_NO_LIBJPEG=1 CARGO_TARGET_DIR=$cross/$triple \
    cargo zigbuild --profile "$profile" --locked --target "$t"
  echo "release: the binary for $t took $((SECONDS - step)) s"
  bin=$cross/$triple/$triple/$profile/halftone
  # Man pages and completions are the same for every target: made once, by the first
  # binary this machine runs natively.
  if [ -z "$host_bin" ] && "$bin" --version >/dev/null 2>&1; then
    host_bin=$bin
  fi
done
if $ci || [ -z "$host_bin" ]; then
  # In CI a no-op: the tests built this binary (with the libjpeg shim, glibc, dynamic).
  cargo build --release --locked
  host_bin=${CARGO_TARGET_DIR:-$root/target}/release/halftone
fi
extras=$(mktemp -d)
trap 'rm -rf "$extras"' EXIT
"$host_bin" man --dir "$extras/man"
mkdir -p "$extras/completions"
"$host_bin" completions bash >"$extras/completions/halftone.bash"
"$host_bin" completions zsh >"$extras/completions/_halftone"
"$host_bin" completions fish >"$extras/completions/halftone.fish"

packaged=("${targets[@]}")
$ci && packaged=("$host_triple" "${targets[@]}")
for t in "${packaged[@]}"; do
  triple=${t%%.2.*}
  name=halftone-$version-$triple
  stage=$extras/$name
  mkdir -p "$stage"
  if $ci && [ "$t" = "$host_triple" ]; then
    cp "$host_bin" "$stage/"
  else
    cp "$cross/$triple/$triple/$profile/halftone" "$stage/"
  fi
  cp -r "$extras/man" "$extras/completions" "$stage/"
  cp README.md LICENSE-MIT LICENSE-APACHE "$stage/"
  # Same bytes for the same tree: sorted names, fixed owner and time.
  tar --sort=name --owner=0 --group=0 --numeric-owner --mtime=@0 -C "$extras" -cf - "$name" \
    | gzip -n -9 >"$dist/$name.tar.gz"
done

# ---- The Python package ------------------------------------------------------------------
# The type stub first, from the option table (python/stub.py; the stub is not kept in git).
python3 python/stub.py "$host_bin"
# One abi3 wheel a target (CPython 3.9 and later), glibc 2.17 (manylinux2014), the same
# Zig as the binaries; then the sdist. With --ci, first the native x86_64 wheel, built where
# `cargo build --release` builds (its dependency builds are shared).
if $ci; then
  echo "release: building the wheel for $host_triple (native)"
  step=$SECONDS
  (cd python && maturin build --release --locked --out "$dist" --quiet)
  echo "release: the wheel for $host_triple took $((SECONDS - step)) s"
fi
for t in "${targets[@]}"; do
  triple=${t%%.2.*}
  case $triple in
    *-musl) wheel_triple=${triple%-musl}-gnu ;;
    *) wheel_triple=$triple ;;
  esac
  rustup target add "$wheel_triple" >/dev/null
  echo "release: building the wheel for $wheel_triple"
  step=$SECONDS
  (cd python && CARGO_TARGET_DIR=$cross/$wheel_triple maturin build --release --locked --zig \
    --target "$wheel_triple" --compatibility manylinux2014 --out "$dist" --quiet)
  echo "release: the wheel for $wheel_triple took $((SECONDS - step)) s"
done
if ! $ci; then
  (cd python && maturin sdist --out "$dist")
fi
for w in "$dist"/halftone-*.whl; do
  auditwheel show "$w" | tr '\n' ' ' | sed 's/  */ /g'
  echo
done

# ---- The npm package -------------------------------------------------------------------
step=$SECONDS
bash web/build.sh
echo "release: the page's build took $((SECONDS - step)) s"
(cd web && npm pack --silent --pack-destination "$dist" >/dev/null)

# ---- The crate ---------------------------------------------------------------------------
# `cargo package` packages the crate and builds it from the package alone; `cargo publish
# --dry-run` then runs the registry's checks on it (metadata, the index) without uploading.
# The Python and web crates are not published (they ship as the wheels and the npm package,
# and build on this crate from the same tree).
if ! $ci; then
  echo "release: cargo package, cargo publish --dry-run"
  cargo package --locked -p halftone
  cargo publish --dry-run --locked --no-verify -p halftone
  cp "${CARGO_TARGET_DIR:-$root/target}/package/halftone-$version.crate" "$dist/"
fi

(cd "$dist" && sha256sum halftone-* >SHA256SUMS)
echo "release: target/dist/ (bytes, file):"
(cd "$dist" && stat -c '%12s  %n' halftone-* SHA256SUMS)
echo "release: built in $((SECONDS - start)) s"

# ---- The checks CI runs ------------------------------------------------------------------
if $ci; then
  step=$SECONDS
  for t in "${targets[@]}"; do
    case $t in
      aarch64-* | armv7-*) HALFTONE_PROFILE=$profile bash scripts/cross-check.sh --goldens "${t%%.2.*}" ;;
    esac
  done
  echo "release: the goldens under qemu took $((SECONDS - step)) s"
  npm_dir=$(mktemp -d)
  trap 'rm -rf "$extras" "$npm_dir"' EXIT
  (cd "$npm_dir" && npm init -y >/dev/null \
    && npm install --no-audit --no-fund --silent "$dist/halftone-web-$version.tgz")
  cp web/test/node-package.mjs "$npm_dir/"
  (cd "$npm_dir" && node node-package.mjs "$root" "$host_bin")
  echo "release: CI checks passed in $((SECONDS - start)) s"
fi
