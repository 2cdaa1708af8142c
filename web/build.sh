#!/usr/bin/env bash
# Builds the WebAssembly package into web/pkg: the .wasm, its JavaScript glue and TypeScript
# types, which the page (index.html) and the npm package (web/package.json) both use. The
# wasm32 target and the wasm-bindgen CLI of the exact version of the wasm-bindgen crate in
# Cargo.lock are installed when missing: `cargo install --locked` first (the dependency
# versions its authors tested); when the registry no longer has one of them (seen: a
# webpki-roots pre-release missing from the index), the newest compatible ones. This script
# is the one place that installs it (CI's browser block runs it through web/test/run.sh).
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
  if ! cargo install wasm-bindgen-cli --version "$version" --locked; then
    echo "web/build.sh: the locked install failed; installing with the newest compatible dependencies" >&2
    cargo install wasm-bindgen-cli --version "$version"
  fi
  echo "web/build.sh: wasm-bindgen-cli $version installed in $((SECONDS - start)) s"
fi
# The `wasm` profile (Cargo.toml): whole-program LTO, one codegen unit.
cargo build --profile wasm --locked --target wasm32-unknown-unknown -p halftone-web
target="${CARGO_TARGET_DIR:-$root/target}"
wasm-bindgen --target web --out-dir web/pkg "$target/wasm32-unknown-unknown/wasm/halftone_web.wasm"
printf 'web/build.sh: web/pkg/halftone_web_bg.wasm %s bytes, %s gzipped\n' \
  "$(wc -c < web/pkg/halftone_web_bg.wasm)" "$(gzip -9 -c web/pkg/halftone_web_bg.wasm | wc -c)"
