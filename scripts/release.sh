#!/usr/bin/env bash
# Builds into target/dist/ the command line as it ships: a static Linux binary for each
# target, with its man pages and shell completions, in a .tar.gz, and SHA256SUMS over them.
#
# Usage: scripts/release.sh [TARGET...]
#   default targets: x86_64-unknown-linux-musl aarch64-unknown-linux-musl
#                    armv7-unknown-linux-gnueabihf.2.17
#
# Cross-building: cargo-zigbuild with Zig as the C compiler and linker, both from PyPI
# (installed into target/zig-venv when missing), so one machine with a Rust toolchain and
# registry access builds every target; no Debian cross toolchain or sysroot is needed.
# x86_64 and aarch64 are musl, fully static (any Linux from 2.6.39 on, any libc). armv7 is
# glibc 2.17 or later (dynamic), because the toolchain's registry here serves no armv7
# musl standard library. JPEG goes through the image crate on every target (no system
# libjpeg to link statically), so every target gives the same bytes; see
# scripts/cross-check.sh, which runs the ARM binaries under qemu-user against the goldens.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
version=$(awk -F'"' '/^version = / { print $2; exit }' Cargo.toml)
dist=$root/target/dist
cross=${CARGO_TARGET_DIR:-$root/target}/cross
# The `dist` profile (thin LTO) for what ships; HALFTONE_PROFILE=release for a quicker build.
profile=${HALFTONE_PROFILE:-dist}
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(x86_64-unknown-linux-musl aarch64-unknown-linux-musl armv7-unknown-linux-gnueabihf.2.17)

if ! command -v cargo-zigbuild >/dev/null 2>&1; then
  venv=$root/target/zig-venv
  if [ ! -x "$venv/bin/cargo-zigbuild" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q ziglang==0.17.1 cargo-zigbuild==0.24.1
  fi
  export PATH="$venv/bin:$PATH"
fi

mkdir -p "$dist"
rm -f "$dist/SHA256SUMS"
host_bin=""
for t in "${targets[@]}"; do
  triple=${t%%.2.*}                      # armv7-unknown-linux-gnueabihf.2.17 -> the triple
  rustup target add "$triple" >/dev/null
  echo "release: building $t"
  HALFTONE_NO_LIBJPEG=1 CARGO_TARGET_DIR=$cross cargo zigbuild --profile "$profile" --locked --target "$t"
  bin=$cross/$triple/$profile/halftone
  # Man pages and completions are the same for every target: made once, by the first
  # binary this machine runs natively.
  if [ -z "$host_bin" ] && "$bin" --version >/dev/null 2>&1; then
    host_bin=$bin
  fi
done
if [ -z "$host_bin" ]; then
  cargo build --release --locked
  host_bin=$root/target/release/halftone
fi
extras=$(mktemp -d)
trap 'rm -rf "$extras"' EXIT
"$host_bin" man --dir "$extras/man"
mkdir -p "$extras/completions"
"$host_bin" completions bash >"$extras/completions/halftone.bash"
"$host_bin" completions zsh >"$extras/completions/_halftone"
"$host_bin" completions fish >"$extras/completions/halftone.fish"

for t in "${targets[@]}"; do
  triple=${t%%.2.*}
  name=halftone-$version-$triple
  stage=$extras/$name
  mkdir -p "$stage"
  cp "$cross/$triple/$profile/halftone" "$stage/"
  cp -r "$extras/man" "$extras/completions" "$stage/"
  cp README.md LICENSE-MIT LICENSE-APACHE "$stage/"
  # Same bytes for the same tree: sorted names, fixed owner and time.
  tar --sort=name --owner=0 --group=0 --numeric-owner --mtime=@0 -C "$extras" -cf - "$name" \
    | gzip -n -9 >"$dist/$name.tar.gz"
  echo "release: $dist/$name.tar.gz ($(stat -c %s "$dist/$name.tar.gz") bytes)"
done
(cd "$dist" && sha256sum halftone-"$version"-*.tar.gz >SHA256SUMS)
echo "release: $dist/SHA256SUMS"
cat "$dist/SHA256SUMS"
