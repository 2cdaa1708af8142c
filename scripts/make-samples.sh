#!/usr/bin/env bash
# Regenerates samples/: renders every built-in scene (halftone render --list) at its own
# size and antialiasing into samples/NAME.png, then halftones a few of them by each
# halftoning method this build of `halftone convert` offers, into samples/halftones/.
#
#   scripts/make-samples.sh            # from the repository root
#
# tests/render.rs checks that the renderer still reproduces samples/*.png.
set -euo pipefail
cd "$(dirname "$0")/.."

cargo build --release --quiet
bin=target/release/halftone

mkdir -p samples/halftones
for scene in $("$bin" render --list | awk '{print $1}'); do
    "$bin" render "$scene" -o "samples/$scene.png"
    echo "samples/$scene.png"
done

# Methods are listed in `convert --help` as "- NAME: ..."; skip those not built yet.
methods=$("$bin" convert --help | sed -n 's/^ *- \([a-z-]*\): .*/\1/p')
has_method() { grep -qx "$1" <<<"$methods"; }

halftone() { # scene, method name for the file, convert options...
    local scene=$1 name=$2
    shift 2
    "$bin" convert "samples/$scene.png" -o "samples/halftones/$scene-$name.png" "$@"
    echo "samples/halftones/$scene-$name.png"
}

for scene in kd-series shading raytrace; do
    has_method threshold && halftone "$scene" threshold --method threshold
    has_method pattern && halftone "$scene" pattern --method pattern --mask seed-3x3 --cell fit
    has_method ordered && halftone "$scene" ordered --method ordered
    has_method diffuse && halftone "$scene" diffuse --method diffuse
done
du -sh samples
