#!/usr/bin/env bash
# Clips halftoned by halftone and by ffmpeg's paletteuse, side by side: per-frame HVS-PSNR,
# flicker in still areas and GIF size (docs/motion.md has the figures and what they mean).
#
# usage: scripts/motion-compare.sh [OUTDIR]     (default: target/motion-compare)
#   HALFTONE=path/to/halftone (default: target/release/halftone)
#   HALFTONE_SKIMAGE_DATA: scikit-image's data folder (default: Debian's python3-skimage)
#   CLIPS="pan zoom …": only these clips
#
# Six clips of 5 s or more at 24–30 fps, 320×240 to 1920×1080, made with ffmpeg from the
# photographs the CI machine has (scikit-image's data, matplotlib's Grace Hopper) and one
# rendered by `halftone render` with a moving light. Each is a grey YUV4MPEG2 stream.
# Every method writes a two-colour GIF (black and white): ours with stable diffusion,
# frame-by-frame Floyd–Steinberg and blue noise; ffmpeg's paletteuse with each of its
# dithers, `diff_mode=rectangle`, on the same black-and-white palette (palettegen, where
# `stats_mode=diff` belongs, makes at least 4 colours, so the palette is given). Each GIF
# is then measured against its clip with `halftone compare --clip` (noise 2 codes).
set -euo pipefail

out=${1:-target/motion-compare}
bin=${HALFTONE:-target/release/halftone}
sk=${HALFTONE_SKIMAGE_DATA:-/usr/lib/python3/dist-packages/skimage/data}
hopper=/usr/share/matplotlib/mpl-data/sample_data/grace_hopper.jpg
clips=${CLIPS:-pan zoom fade inset kenburns render}

for tool in ffmpeg python3; do
    command -v "$tool" >/dev/null || { echo "motion-compare: $tool is missing (apt-get install -y $tool)" >&2; exit 1; }
done
[ -x "$bin" ] || { echo "motion-compare: no binary at $bin (cargo build --release)" >&2; exit 1; }
for f in "$sk/astronaut.png" "$sk/coffee.png" "$sk/chelsea.png" "$sk/camera.png" "$sk/rocket.jpg" "$hopper"; do
    [ -f "$f" ] || { echo "motion-compare: $f is missing (python3-skimage, python-matplotlib-data)" >&2; exit 1; }
done
mkdir -p "$out"
ff() { ffmpeg -nostdin -hide_banner -loglevel error -y "$@"; }
y4m=(-pix_fmt gray -f yuv4mpegpipe -strict -1)

make_clip() {
    local name=$1 f="$out/$1.y4m"
    [ -s "$f" ] && return
    case $name in
    pan) # 320×240, 30 fps, 6 s: a pan across the astronaut.
        ff -loop 1 -i "$sk/astronaut.png" -t 6 -r 30 \
            -vf "crop=320:240:x='(iw-320)*t/6':y=100" "${y4m[@]}" "$f" ;;
    zoom) # 640×480, 25 fps, 5 s: a zoom into the coffee cup.
        ff -loop 1 -i "$sk/coffee.png" -vf \
            "scale=1280:-2,zoompan=z='min(1+0.004*on,1.5)':x='iw/2-iw/zoom/2':y='ih/2-ih/zoom/2':d=1:s=640x480:fps=25" \
            -frames:v 125 "${y4m[@]}" "$f" ;;
    fade) # 1280×720, 24 fps, 6 s: cat, then a 2 s cross-fade to Grace Hopper; 2 s still at each end.
        ff -loop 1 -t 4 -r 24 -i "$sk/chelsea.png" -loop 1 -t 4 -r 24 -i "$hopper" -filter_complex \
            "[0]scale=1280:720:force_original_aspect_ratio=increase,crop=1280:720,setsar=1,format=gray[a];[1]scale=1280:720:force_original_aspect_ratio=increase,crop=1280:720,setsar=1,format=gray[b];[a][b]xfade=transition=fade:duration=2:offset=2" \
            "${y4m[@]}" "$f" ;;
    inset) # 1920×1080, 25 fps, 5 s: the camera man still, an inset photo moving across him.
        ff -loop 1 -i "$sk/camera.png" -loop 1 -i "$sk/astronaut.png" -filter_complex \
            "[0]scale=1920:1080,setsar=1[bg];[1]scale=400:400[fg];[bg][fg]overlay=x='100+250*t':y='300+40*t'" \
            -t 5 -r 25 "${y4m[@]}" "$f" ;;
    kenburns) # 960×540, 30 fps, 5 s: a slow push in on the rocket (every pixel moves a little).
        ff -loop 1 -i "$sk/rocket.jpg" -vf \
            "scale=1920:-2,zoompan=z='1+0.0012*on':x='iw/2-iw/zoom/2':y='ih/3-ih/zoom/3':d=1:s=960x540:fps=30" \
            -frames:v 150 "${y4m[@]}" "$f" ;;
    render) # 480×360, 25 fps, 5 s: the ray-traced scene with its point light moving.
        local dir="$out/render-frames"
        mkdir -p "$dir"
        for i in $(seq 0 124); do
            x=$(python3 -c "print(round(-6 + 12 * $i / 124, 3))")
            sed -e "s/^position = \[-6.0, 9.0, 6.0\]/position = [$x, 9.0, 6.0]/" scenes/raytrace.toml >"$dir/s.toml"
            "$bin" render "$dir/s.toml" -o "$(printf '%s/%04d.png' "$dir" "$i")" --size 480x360 --aa super
        done
        ff -framerate 25 -i "$dir/%04d.png" "${y4m[@]}" "$f" ;;
    esac
}

pal="$out/bw-palette.png"
# paletteuse wants 256 entries: 128 black then 128 white.
ff -f lavfi -i "color=black:s=16x8" -f lavfi -i "color=white:s=16x8" -filter_complex vstack -frames:v 1 "$pal"

results="$out/results.tsv"
printf 'clip\tsize\tframes\tmethod\thvs_psnr_db\tflicker\tgif_bytes\tcpu_s\n' >"$results"
for clip in $clips; do
    make_clip "$clip"
    src="$out/$clip.y4m"
    read -r w h frames < <(python3 - "$src" <<'EOF'
import os, sys
f = open(sys.argv[1], "rb")
head = f.readline().split()
w = int([t for t in head if t.startswith(b"W")][0][1:]); h = int([t for t in head if t.startswith(b"H")][0][1:])
print(w, h, os.path.getsize(sys.argv[1]) // (w * h + 6))
EOF
)
    every=1
    [ "$w" -ge 1280 ] && every=5
    run() { # method-name gif: measure the GIF, one row of results
        local m=$1 gif=$2
        "$bin" compare --clip --every "$every" --json "$src" "$gif" >"$gif.json"
        python3 - "$gif.json" "$clip" "${w}x$h" "$m" "$gif" >>"$results" <<'EOF'
import json, os, sys
j = json.load(open(sys.argv[1]))
print("\t".join([sys.argv[2], sys.argv[3], str(j["frames"]), sys.argv[4],
                 "%.2f" % j["hvs_psnr_db_mean"], "%.5f" % j["flicker"],
                 str(os.path.getsize(sys.argv[5])), os.environ.get("CPU", "")]))
EOF
    }
    timed() { # seconds of CPU of a command, into $CPU
        local s
        s=$( { /usr/bin/time -f '%U %S' "$@" 2>&1 >/dev/null; } | tail -1)
        CPU=$(python3 -c "a,b='$s'.split(); print('%.2f' % (float(a)+float(b)))")
        export CPU
    }
    for m in stable frame blue-noise; do
        gif="$out/$clip-ours-$m.gif"
        case $m in
        stable) args=(-m diffuse) ;;
        frame) args=(-m diffuse --temporal frame) ;;
        blue-noise) args=(-m ordered --mask blue-noise-64) ;;
        esac
        timed "$bin" convert "$src" -o "$gif" "${args[@]}"
        run "halftone $m" "$gif"
    done
    for d in floyd_steinberg sierra2 sierra2_4a heckbert bayer none; do
        gif="$out/$clip-ffmpeg-$d.gif"
        timed ffmpeg -nostdin -loglevel error -y -i "$src" -i "$pal" -lavfi \
            "[0:v]format=rgb24[x];[x][1:v]paletteuse=dither=$d:diff_mode=rectangle" "$gif"
        run "ffmpeg $d" "$gif"
    done
done
column -t -s $'\t' "$results"
