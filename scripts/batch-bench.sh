#!/usr/bin/env bash
# Batch scaling: 200 two-megapixel PNGs (1732x1155, photo-like grey and colour) halftoned to
# PBM with Floyd-Steinberg, whole run, --jobs 1 against --jobs 2, with peak memory.
#
# Usage: scripts/batch-bench.sh [-n FILES] [-r RUNS] [-m METHOD_ARGS] [--no-build]
# Needs hyperfine and GNU time (Debian packages hyperfine, time) and python3 with PIL
# (python3-pil) to make the inputs, which are kept in target/batch-bench/in.
set -euo pipefail
cd "$(dirname "$0")/.."
files=200
runs=3
method="--method diffuse --kernel floyd-steinberg"
build=1
while [ $# -gt 0 ]; do
    case "$1" in
        -n) files="$2"; shift 2 ;;
        -r) runs="$2"; shift 2 ;;
        -m) method="$2"; shift 2 ;;
        --no-build) build=0; shift ;;
        -h|--help) sed -n '2,8p' "$0"; exit 0 ;;
        *) echo "batch-bench: unknown argument $1" >&2; exit 2 ;;
    esac
done
work=target/batch-bench
mkdir -p "$work"
[ "$build" = 1 ] && cargo build --release --quiet
bin=target/release/halftone

if [ "$(find "$work/in" -name '*.png' 2>/dev/null | wc -l)" != "$files" ]; then
    rm -rf "$work/in"
    mkdir -p "$work/in"
    py=""
    for p in /usr/bin/python3 python3; do
        if command -v "$p" >/dev/null && "$p" -c 'import PIL' 2>/dev/null; then py="$p"; break; fi
    done
    [ -n "$py" ] || { echo "batch-bench: python3 with PIL needed to make inputs" >&2; exit 1; }
    "$py" - "$work/in" "$files" <<'PY'
import random, sys
from PIL import Image, ImageDraw, ImageFilter
out, n = sys.argv[1], int(sys.argv[2])
W, H = 1732, 1155  # 2.0 megapixels
random.seed(7)
base = []
for k in range(10):  # ten distinct pictures, each written n/10 times under its own name
    mode = "RGB" if k % 2 else "L"
    im = Image.linear_gradient("L").resize((W, H)).convert(mode)
    d = ImageDraw.Draw(im)
    for _ in range(40):
        x, y, r = random.randrange(W), random.randrange(H), random.randrange(20, 250)
        fill = tuple(random.randrange(256) for _ in range(3)) if mode == "RGB" else random.randrange(256)
        d.ellipse((x - r, y - r, x + r, y + r), fill=fill)
    base.append(im.filter(ImageFilter.GaussianBlur(3)))
for i in range(n):
    base[i % 10].save(f"{out}/photo-{i:03d}.png", compress_level=1)
PY
fi

for jobs in 1 2; do
    rm -rf "$work/out$jobs"
done
hyperfine --style basic --runs "$runs" --warmup 1 \
    --prepare "rm -rf $work/out1 $work/out2" \
    --export-json "$work/hyperfine.json" \
    --command-name "jobs=1" "$bin batch $work/in -o $work/out1 --format pbm $method --jobs 1 -q" \
    --command-name "jobs=2" "$bin batch $work/in -o $work/out2 --format pbm $method --jobs 2 -q" >&2

echo "| run | wall time (mean ± σ) | speed-up | peak RSS |"
echo "|---|---|---|---|"
t1=""
for jobs in 1 2; do
    read -r mean sd < <(python3 -c "import json; r=json.load(open('$work/hyperfine.json'))['results'][$((jobs - 1))]; print(r['mean'], r['stddev'] or 0)")
    [ -z "$t1" ] && t1=$mean
    rm -rf "$work/out$jobs"
    kb=$(/usr/bin/time -v "$bin" batch "$work/in" -o "$work/out$jobs" --format pbm $method --jobs "$jobs" -q 2>&1 >/dev/null |
        awk -F': ' '/Maximum resident set size/ {print $2}')
    awk -v j="$jobs" -v m="$mean" -v s="$sd" -v t="$t1" -v k="$kb" \
        'BEGIN { printf "| --jobs %d | %.2f s ± %.2f | %.2f× | %.0f MiB |\n", j, m, s, t / m, k / 1024 }'
done
echo
echo "$files PNGs of 2.0 MP ($(du -sm "$work/in" | cut -f1) MiB), method: $method;" \
    "$(nproc) CPUs ($(lscpu | awk -F': *' '/Model name/ {print $2; exit}')); $(date -u +%Y-%m-%d)."
