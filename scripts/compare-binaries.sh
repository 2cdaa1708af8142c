#!/usr/bin/env bash
# Runs the same halftone commands with two binaries and compares every file they write, byte
# for byte: the README's `halftone …` lines (those that need no network, root or a scheduler)
# and a set covering every method, format, colour mode, preset, CMYK plates and batch.
# (Printed pages are given a resolution: without one, a newer binary takes the image's or
# 300 dpi where an older one took 72.)
#
# Usage: scripts/compare-binaries.sh OLD_BINARY NEW_BINARY
# Prints one line a command and a closing `N passed, M failed`; exits 1 on any difference.
set -uo pipefail
old=$(realpath "$1")
new=$(realpath "$2")
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The README's commands: lines of its shell blocks that start with `halftone `, without
# pipes to other programs, output to stdout or interactive parts.
readme_cmds() {
  awk '/^```(sh|bash|console)?$/{inb=!inb; next} inb' "$root/README.md" \
    | sed -e 's/^\$ //' \
    | grep -E '^halftone (convert|batch|patterns|masks|compare|render|press|sheet) ' \
    | grep -vE '\||<\(|>|\$\(|lp |curl|sudo|--help|--shard auto' || true
}

cmds=()
while IFS= read -r line; do cmds+=("$line"); done < <(readme_cmds)
s=samples
cmds+=(
  "halftone convert $s/raytrace.png -o a.pbm"
  "halftone convert $s/raytrace.png -o a.png --levels 4"
  "halftone convert $s/raytrace.png -o a.pgm --method threshold --threshold 50%"
  "halftone convert $s/raytrace.png -o a.png --method pattern --mask seed-3x3 --cell expand"
  "halftone convert $s/raytrace.png -o a.pgm --method pattern --mask seed-2x2 --levels 4"
  "halftone convert $s/raytrace.png -o a.tif --method ordered --mask blue-noise-64 --compression g4 --dpi 300"
  "halftone convert $s/raytrace.png -o a.bmp --method ordered --mask bayer-8 --levels 4"
  "halftone convert $s/raytrace.png -o a.pbm --method diffuse --kernel ostromoukhov"
  "halftone convert $s/raytrace.png -o a.pbm --method diffuse --kernel tded"
  "halftone convert $s/raytrace.png -o a.pbm --method diffuse --kernel riemersma"
  "halftone convert $s/raytrace.png -o a.pbm --hysteresis 1.5"
  "halftone convert $s/raytrace.png -o a.pbm --method dbs --width 160"
  "halftone convert $s/raytrace.png -o a.pbm --method dbs --width 120 --printer-model dot-overlap --dot-ratio 1.25"
  "halftone convert $s/raytrace.png -o a.pbm --method screen --lpi 85 --angle 30 --spot ellipse --dpi 600"
  "halftone convert $s/color-balls.png -o a.png --method diffuse --palette epaper-7"
  "halftone convert $s/color-balls.png -o a.ppm --color rgb --method ordered --mask bayer-4"
  "halftone convert $s/color-balls.png -o plates.tif --color cmyk --method screen --lpi 60 --dpi 600 --width 300 --preview prev.png"
  "halftone convert $s/color-balls.png -o plates.pdf --color cmyk --width 200 --dpi 300"
  "halftone convert $s/color-balls.png -o plates.png --color cmyk --separation naive --gcr 80 --width 200"
  "halftone convert $s/raytrace.png -o a.pdf --dpi 300 --page a4 --content auto"
  "halftone convert $s/raytrace.png -o a.ps --dpi 300"
  "halftone convert $s/raytrace.png -o a.pcl --dpi 300"
  "halftone convert $s/raytrace.png -o r.escpos --preset thermal-203"
  "halftone convert $s/raytrace.png -o l.zpl --preset label-203"
  "halftone convert $s/raytrace.png -o l.pcl --preset laser-600"
  "halftone convert $s/raytrace.png -o e.png --preset eink-4grey --rotate auto"
  "halftone convert $s/raytrace.png -o n.tif --preset newsprint --width 400"
  "halftone convert $s/raytrace.png -o g.pbm --gamma 1.4 --dot-gain 12 --invert"
  "halftone convert $s/raytrace.png -o w.pbm --width 333 --max-memory 1M"
  "halftone convert $s/raytrace.png -o f.png --fit 200x100 --levels 3 --device-levels"
  "halftone convert $s/raytrace.png -o t.pbm --transfer presets/thermal-203.csv"
  "halftone batch $s/raytrace.png $s/shading.png -o outdir --method ordered"
  "halftone batch $s/raytrace.png $s/shading.png -o book.pdf --dpi 300"
)

pass=0
fail=0
for c in "${cmds[@]}"; do
  for side in old new; do
    d="$work/$side"
    rm -rf "$d"
    mkdir -p "$d"
    cp -r "$root/samples" "$root/presets" "$d/"
    # The README's commands name the samples, and a photo, in the current folder.
    cp "$root"/samples/*.png "$d/"
    photo=/usr/share/matplotlib/mpl-data/sample_data/grace_hopper.jpg
    [ -f "$photo" ] && cp "$photo" "$d/photo.jpg"
    bin=$([ "$side" = old ] && echo "$old" || echo "$new")
    # shellcheck disable=SC2086
    (cd "$d" && eval "\"$bin\" ${c#halftone }" >"$d.stdout" 2>"$d.stderr"; echo $? >"$d.rc")
    rm -rf "$d/samples" "$d/presets"
    (cd "$root/samples" && for f in *.png; do cmp -s "$f" "$d/$f" && rm -f "$d/$f"; done)
    rm -f "$d/photo.jpg"
  done
  if [ "$(cat "$work/old.rc")" != "$(cat "$work/new.rc")" ]; then
    echo "DIFFERENT EXIT ($(cat "$work/old.rc") vs $(cat "$work/new.rc")): $c"
    head -c 300 "$work/new.stderr"
    fail=$((fail + 1))
  elif ! diff -r -q "$work/old" "$work/new" >/dev/null || ! cmp -s "$work/old.stdout" "$work/new.stdout"; then
    echo "DIFFERENT FILES: $c"
    diff -r -q "$work/old" "$work/new" | head -5
    fail=$((fail + 1))
  else
    n=$(find "$work/new" -type f | wc -l)
    echo "same ($n files, exit $(cat "$work/new.rc")): $c"
    pass=$((pass + 1))
  fi
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
