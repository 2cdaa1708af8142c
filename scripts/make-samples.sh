#!/usr/bin/env bash
# Regenerates samples/: renders every built-in scene (halftone render --list) at its own
# size and antialiasing into samples/NAME.png, then halftones a few of them by each
# halftoning method this build of `halftone convert` offers, into samples/halftones/.
#
#   scripts/make-samples.sh            # from the repository root
#
# tests/it/render.rs checks that the renderer still reproduces samples/*.png.
set -euo pipefail
cd "$(dirname "$0")/.."

cargo build --release --quiet
bin=target/release/halftone

mkdir -p samples/halftones
for scene in $("$bin" render --list | awk '{print $1}'); do
    "$bin" render "$scene" -o "samples/$scene.png"
    echo "samples/$scene.png"
done

# The methods are the possible values listed under --method in `convert --help`
# ("- NAME: ..."); those not built yet are skipped.
methods=$("$bin" convert --help | awk '
    /^ *-m, --method/ { on = 1; next }
    on && /^  +-(-|[a-zA-Z],)/ { on = 0 }
    on && match($0, /^ *- [a-z-]+:/) { v = substr($0, RSTART, RLENGTH); sub(/^ *- /, "", v); sub(/:$/, "", v); print v }')
has_method() { grep -qx "$1" <<<"$methods"; }

halftone() { # scene, method name for the file, convert options...
    local scene=$1 name=$2
    shift 2
    "$bin" convert "samples/$scene.png" -o "samples/halftones/$scene-$name.png" "$@"
    echo "samples/halftones/$scene-$name.png"
}

for scene in kd-series shading raytrace; do
    if has_method threshold; then halftone "$scene" threshold --method threshold; fi
    if has_method pattern; then
        halftone "$scene" pattern --method pattern --mask seed-3x3 --cell fit
    fi
    if has_method ordered; then halftone "$scene" ordered --method ordered; fi
    if has_method diffuse; then halftone "$scene" diffuse --method diffuse; fi
done
du -sh samples
