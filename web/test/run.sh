#!/usr/bin/env bash
# The browser test: builds the WebAssembly package and the CLI, installs Debian's Chromium
# and puppeteer-core when missing, then drives the page (web/test/test.mjs). Ends with
# `web: N passed, M failed` and a non-zero status on any failure.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$root"
start=$SECONDS
if ! command -v chromium >/dev/null; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
fi
web/build.sh
cargo build --release --bin halftone
(cd web/test && npm ci --no-audit --no-fund --silent)
echo "web/test/run.sh: built in $((SECONDS - start)) s"
node web/test/test.mjs
