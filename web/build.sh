#!/usr/bin/env bash
# Builds the WebAssembly package into web/pkg: the wasm32 target and the wasm-bindgen CLI
# of the exact version of the wasm-bindgen crate in Cargo.lock are installed when missing.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
version="$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/"/, "", $3); print $3; exit }' Cargo.lock)"
if [ -z "$version" ]; then
  echo "web/build.sh: no wasm-bindgen in Cargo.lock" >&2
  exit 1
fi
rustup target list --installed | grep -qx wasm32-unknown-unknown || rustup target add wasm32-unknown-unknown
if [ "$(wasm-bindgen --version 2>/dev/null | awk '{print $2}')" != "$version" ]; then
  start=$SECONDS
  cargo install wasm-bindgen-cli --version "$version" --locked
  echo "web/build.sh: wasm-bindgen-cli $version installed in $((SECONDS - start)) s"
fi
cargo build --release --target wasm32-unknown-unknown -p halftone-web
wasm-bindgen --target web --no-typescript --out-dir web/pkg \
  target/wasm32-unknown-unknown/release/halftone_web.wasm
printf 'web/build.sh: web/pkg/halftone_web_bg.wasm %s bytes, %s gzipped\n' \
  "$(wc -c < web/pkg/halftone_web_bg.wasm)" "$(gzip -9 -c web/pkg/halftone_web_bg.wasm | wc -c)"
