#!/usr/bin/env bash
# Regenerates the charts, tables and pictures under assets/ that README.md and docs/ show,
# from this build of halftone, so that they cannot drift from the tool:
#
#   assets/bench/     `halftone bench --stability`: results.csv/json, chart, stability map
#                     (run outside the repository, on the sample pictures built into the
#                     binary and a grey ramp: what a user gets from `halftone bench`)
#   assets/bench/table.md   the "which method" table of the README, from results.csv
#   assets/newcomer/  the README's pictures (Floyd–Steinberg photo, contact sheet, e-paper,
#                     threshold, the seed-3x3 pattern table)
#   assets/accuracy/  the DBS chart, only with PHOTOS=folder (scikit-image's six photos)
#
#   scripts/make-assets.sh               # from anywhere; takes about 10 minutes on 2 cores
#   RUNS=7 scripts/make-assets.sh        # more runs a method (default 5)
#   SKIP_BENCH=1 scripts/make-assets.sh  # pictures only
#
# Throughput depends on the machine and its load; the accuracy and stability figures are
# exact and repeatable. Record the machine with the figures when you quote them.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

cargo build --release --quiet
bin=$root/target/release/halftone
photo=/usr/share/matplotlib/mpl-data/sample_data/grace_hopper.jpg
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

if [ -z "${SKIP_BENCH:-}" ]; then
    # Outside the repository, so bench takes its built-in sample pictures.
    (cd "$work" && "$bin" bench --stability --runs "${RUNS:-5}" -o "$work/bench" >"$work/bench.md")
    mkdir -p assets/bench
    cp "$work"/bench/{results.csv,results.json,chart.png,chart.svg,heatmap.png,heatmap.svg,stability.csv,stability.json,stability.md} assets/bench/
    # The README's table: each method's mean over the images, throughput as total
    # megapixels over total seconds, from results.csv.
    python3 - assets/bench/results.csv >assets/bench/table.md <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
keys = list(dict.fromkeys(r["key"] for r in rows))
print("| method | MP/s | HVS-PSNR dB | tone bias | L* RMS |")
print("|---|---:|---:|---:|---:|")
for k in keys:
    rs = [r for r in rows if r["key"] == k]
    mean = lambda f: sum(float(r[f]) for r in rs) / len(rs)
    mp = sum(float(r["megapixels"]) for r in rs) / sum(float(r["median_seconds"]) for r in rs)
    print(f"| {k} | {mp:.0f} | {mean('hvs_psnr_db'):.2f} | {mean('tone_bias'):+.4f} | {mean('lstar_rms'):.2f} |")
PY
    {
        echo "Measured $(date -u +%Y-%m-%d) on $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'),"
        echo "$(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg) at the end."
    } >assets/bench/machine.txt
    echo "assets/bench/ (see assets/bench/machine.txt)"
fi

mkdir -p assets/newcomer
cd "$work"
"$bin" render raytrace -o raytrace.png
"$bin" convert raytrace.png -o "$root/assets/newcomer/rt-threshold.png" --method threshold --threshold 50%
"$bin" patterns --mask seed-3x3 -o "$root/assets/newcomer/seed-3x3-table.png"
if [ -f "$photo" ]; then
    "$bin" convert "$photo" -o "$root/assets/newcomer/hopper-fs.png" --width 320
    "$bin" sheet "$photo" -o "$root/assets/newcomer/hopper-sheet.png" --tile 200 >/dev/null
    "$bin" convert "$photo" -o "$root/assets/newcomer/hopper-eink.png" --preset eink-4grey --rotate auto
else
    echo "note: $photo is missing (apt-get install python-matplotlib-data); photo pictures kept" >&2
fi
echo "assets/newcomer/"

if [ -n "${PHOTOS:-}" ]; then
    "$bin" bench --images "$PHOTOS" --methods diffuse-floyd-steinberg,diffuse-ostromoukhov,diffuse-tded,dbs,model-dbs-1.25,diffuse-hysteresis-1.5,ordered-bayer-8,ordered-cluster-8 \
        -o "$work/accuracy" >/dev/null
    cp "$work"/accuracy/{chart.png,chart.svg,results.csv} "$root/assets/accuracy/"
    echo "assets/accuracy/"
fi
