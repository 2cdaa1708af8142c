#!/usr/bin/env bash
# halftone against its peers, whole process, one machine, one run: a 24-megapixel grey
# PGM to a PBM. Three groups, each timed by hyperfine with peak memory from /usr/bin/time:
#
#   ordered   halftone --method ordered --mask bayer-8 | pamditherbw -dither8 (netpbm) |
#             convert-im6.q16 -ordered-dither o8x8 (ImageMagick 6)
#   fs        halftone --method diffuse (Floyd-Steinberg, linear light) | Pillow convert('1') |
#             pamditherbw -fs | convert-im6.q16 -dither FloydSteinberg -monochrome
#   basic     halftone --method threshold and --method pattern (seed-3x3, fit) |
#             pamthreshold -simple (netpbm)
#   jpeg      24 MP JPEG q90 to PBM, Floyd-Steinberg | Pillow open→convert('L')→convert('1')
#   thermal   24 MP JPEG to --preset thermal-203 (384 dots wide) | Pillow draft + Lanczos +
#             convert('1') | vipsthumbnail -s 384
#   rgb       24 MP RGB PPM, --color rgb Floyd-Steinberg, next to the grey PGM of the same photo
#   palette   24 MP RGB PPM, --palette rgb-8 | Pillow quantize(palette, FLOYDSTEINBERG)
#
# The colour groups (jpeg, thermal, rgb, palette) use a photo: scikit-image's astronaut
# (Debian's python3-skimage) scaled to 6000x4000, else the grey scene tinted; made once in
# target/peer-bench/. HALFTONE=path picks the binary (default target/release/halftone).
#
# Usage: scripts/peer-bench.sh [-i INPUT.pgm] [-o TABLE.md] [-r RUNS] [-g GROUPS] [--no-build]
# GROUPS is a comma-separated subset of ordered,fs,basic,jpeg,thermal,rgb,palette (default: all).
# Without -i a smooth photo-like 6000x4000 PGM is made with Python's PIL (Debian's
# python3-pil). Peers come from Debian's packages: netpbm, imagemagick-6.q16, hyperfine,
# time. A missing peer is skipped with a note. The markdown table (mean ± σ, relative
# speed, peak RSS) goes to stdout and to TABLE.md (default target/peer-bench/peer-bench.md).
set -euo pipefail

cd "$(dirname "$0")/.."
work=target/peer-bench
input=""
table="$work/peer-bench.md"
runs=5
build=1
groups=ordered,fs,basic,jpeg,thermal,rgb,palette
while [ $# -gt 0 ]; do
    case "$1" in
        -i) input="$2"; shift 2 ;;
        -o) table="$2"; shift 2 ;;
        -r) runs="$2"; shift 2 ;;
        -g) groups="$2"; shift 2 ;;
        --no-build) build=0; shift ;;
        -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
        *) echo "peer-bench: unknown argument $1" >&2; exit 2 ;;
    esac
done
mkdir -p "$work"
note() { echo "peer-bench: $*" >&2; }

if ! command -v hyperfine >/dev/null; then
    note "hyperfine is required (Debian package hyperfine)"; exit 1
fi

if [ "$build" = 1 ]; then
    cargo build --release --quiet
fi
halftone=${HALFTONE:-target/release/halftone}

# --- input -----------------------------------------------------------------------------
if [ -z "$input" ]; then
    input="$work/photo-6000x4000.pgm"
    if [ ! -s "$input" ]; then
        py=""
        for p in python3 /usr/bin/python3; do
            if command -v "$p" >/dev/null && "$p" -c 'import PIL' 2>/dev/null; then py="$p"; break; fi
        done
        if [ -z "$py" ]; then
            note "no -i given and no python3 with PIL to make one"; exit 1
        fi
        note "making $input (6000x4000 grey, smooth and photo-like)"
        "$py" - "$input" <<'EOF'
import random, sys
from PIL import Image, ImageChops, ImageDraw, ImageFilter, ImageOps
W, H = 6000, 4000
random.seed(1)
# Soft light: a diagonal gradient blended with an off-centre radial highlight.
lin = Image.linear_gradient("L")
grad = Image.blend(lin, lin.transpose(Image.ROTATE_90), 0.5).resize((W, H), Image.BICUBIC)
spot = ImageOps.invert(Image.radial_gradient("L")).resize((W, H), Image.BICUBIC)
spot = ImageChops.offset(spot, -W // 5, -H // 6)
base = Image.blend(grad, spot, 0.45)
# Zero-mean texture at a few scales (blurred, upsampled noise), like foliage or fabric.
for size, gain in ((40, 0.5), (400, 0.35), (3000, 0.2)):
    n = Image.effect_noise((size, size * H // W), 64).filter(ImageFilter.GaussianBlur(1))
    n = n.resize((W, H), Image.BICUBIC).point(lambda v, g=gain: int(128 + (v - 128) * g))
    base = ImageChops.add(base, n, scale=1.0, offset=-128)
# Hard edges: a few discs of other tones, then a slight blur as a lens gives.
d = ImageDraw.Draw(base)
for _ in range(25):
    x, y = random.randrange(W), random.randrange(H)
    r = random.randrange(40, 300)
    d.ellipse((x - r, y - r, x + r, y + r), fill=random.randrange(30, 230))
base = ImageOps.autocontrast(base.filter(ImageFilter.GaussianBlur(2)), cutoff=0.5)
base.save(sys.argv[1])
EOF
    fi
fi
[ -s "$input" ] || { note "$input: no such file"; exit 1; }

# --- one group: time, measure memory, print a table -------------------------------------
pixels=$(head -c 64 "$input" | tr '\n' ' ' | awk '{ print $2 * $3 }')
input_mib=$(du -m "$input" | cut -f1)
cpu=$(lscpu 2>/dev/null | awk -F': *' '/Model name/ {print $2; exit}')
pillow=""
for p in /usr/bin/python3 python3; do
    if command -v "$p" >/dev/null && "$p" -c 'import PIL' 2>/dev/null; then pillow="$p"; break; fi
done

names=()
cmds=()
add() { # name, command; the command is tried once and skipped with a note if it fails
    if bash -c "$2" >/dev/null 2>"$work/try.err"; then
        names+=("$1")
        cmds+=("$2")
    else
        note "skipping $1: $(head -c 300 "$work/try.err")"
    fi
}
has() { command -v "$1" >/dev/null; }

run_group() { # title
    local title=$1
    [ ${#cmds[@]} -gt 0 ] || { note "$title: nothing to run"; return; }
    local hf_args=(--warmup 1 --runs "$runs" --export-json "$work/hyperfine.json" --style basic)
    for i in "${!cmds[@]}"; do
        hf_args+=(--command-name "${names[$i]}" "${cmds[$i]}")
    done
    hyperfine "${hf_args[@]}" >&2
    local rss=()
    for i in "${!cmds[@]}"; do
        if [ -x /usr/bin/time ]; then
            kb=$(/usr/bin/time -v bash -c "${cmds[$i]}" 2>&1 >/dev/null |
                awk -F': ' '/Maximum resident set size/ {print $2}')
            rss+=("$(awk -v k="$kb" 'BEGIN { printf "%.1f MiB", k / 1024 }')")
        else
            rss+=("n/a")
        fi
    done
    mapfile -t rows < <(python3 -c 'import json,sys
for r in json.load(sys.stdin)["results"]: print(r["mean"], r["stddev"] or 0)' <"$work/hyperfine.json")
    local fastest
    fastest=$(printf '%s\n' "${rows[@]}" | awk 'NR == 1 || $1 < m { m = $1 } END { print m }')
    {
        echo "**$title** — ${what:-$(basename "$input") ($((pixels / 1000000)) MP grey PGM, $input_mib MiB) to PBM}," \
            "whole process, mean ± σ of $runs runs after 1 warm-up:"
        echo
        echo "| command | mean ± σ | relative | peak RSS |"
        echo "|---|---|---|---|"
        local i=0
        for row in "${rows[@]}"; do
            read -r mean sd <<<"$row"
            awk -v n="${names[$i]}" -v m="$mean" -v s="$sd" -v f="$fastest" -v r="${rss[$i]}" \
                'BEGIN { printf "| %s | %.1f ms ± %.1f | %.1f× | %s |\n", n, m * 1000, s * 1000, m / f, r }'
            i=$((i + 1))
        done
        echo
    } | tee -a "$table"
    names=()
    cmds=()
}

: >"$table"
h="$halftone convert $input"
if [[ ",$groups," == *",ordered,"* ]]; then
    add "halftone ordered bayer-8" "$h -o $work/o-halftone.pbm --method ordered --mask bayer-8"
    if has pamditherbw; then
        # pamditherbw writes a PAM of one byte a pixel; pamtopnm makes it the same PBM.
        add "netpbm pamditherbw -dither8" "pamditherbw -dither8 $input > $work/o-netpbm.pam"
        has pamtopnm && add "netpbm pamditherbw -dither8 \| pamtopnm" \
            "pamditherbw -dither8 $input | pamtopnm > $work/o-netpbm.pbm"
    fi
    has convert-im6.q16 && add "ImageMagick -ordered-dither o8x8" \
        "convert-im6.q16 $input -ordered-dither o8x8 $work/o-im.pbm"
    run_group "Ordered dithering, 8×8 Bayer"
fi
if [[ ",$groups," == *",fs,"* ]]; then
    add "halftone diffuse floyd-steinberg (linear light)" \
        "$h -o $work/fs-halftone.pbm --method diffuse --kernel floyd-steinberg"
    add "halftone diffuse floyd-steinberg --no-serpentine" \
        "$h -o $work/fs-halftone-raster.pbm --method diffuse --kernel floyd-steinberg --no-serpentine"
    [ -n "$pillow" ] && add "Pillow convert('1') (encoded values)" \
        "$pillow -c \"from PIL import Image; Image.open('$input').convert('1').save('$work/fs-pil.pbm')\""
    has pamditherbw && add "netpbm pamditherbw -fs" "pamditherbw -fs $input > $work/fs-netpbm.pam"
    has convert-im6.q16 && add "ImageMagick -dither FloydSteinberg -monochrome" \
        "convert-im6.q16 $input -dither FloydSteinberg -monochrome $work/fs-im.pbm"
    run_group "Floyd–Steinberg error diffusion"
fi
if [[ ",$groups," == *",basic,"* ]]; then
    add "halftone threshold" "$h -o $work/t-halftone.pbm --method threshold"
    add "halftone pattern seed-3x3 fit" "$h -o $work/p-halftone.pbm --method pattern"
    add "halftone pattern seed-3x3 expand (9× output)" \
        "$h -o $work/pe-halftone.pbm --method pattern --cell expand"
    has pamthreshold && add "netpbm pamthreshold -simple" \
        "pamthreshold -simple $input > $work/t-netpbm.pam"
    run_group "Threshold and pattern"
fi
# --- colour and JPEG groups: a photo ------------------------------------------------------
if [[ ",$groups," =~ ,(jpeg|thermal|rgb|palette), ]]; then
    [ -n "$pillow" ] || { note "the colour groups need python3 with PIL"; exit 1; }
    ppm="$work/photo-6000x4000.ppm"
    jpg="$work/photo-6000x4000-q90.jpg"
    pgm="$work/photo-6000x4000-grey.pgm"
    if [ ! -s "$ppm" ] || [ ! -s "$jpg" ] || [ ! -s "$pgm" ]; then
        note "making $ppm, $jpg and $pgm"
        "$pillow" - "$input" "$ppm" "$jpg" "$pgm" <<'EOF'
import os, sys
from PIL import Image, ImageChops
grey, ppm, jpg, pgm = sys.argv[1:]
W, H = 6000, 4000
src = "/usr/lib/python3/dist-packages/skimage/data/astronaut.png"
if os.path.exists(src):
    im = Image.open(src).convert("RGB").resize((W, H), Image.LANCZOS)
    # Fine grain, as a real 24 MP sensor has: scaling up a small photo leaves none.
    noise = Image.effect_noise((W, H), 6).convert("RGB")
    im = ImageChops.add(im, noise, scale=1.0, offset=-128)
else:
    g = Image.open(grey).convert("L")
    im = Image.merge("RGB", (g, g.rotate(180), g.transpose(Image.FLIP_LEFT_RIGHT)))
im.save(ppm)
im.save(jpg, quality=90)
im.convert("L").save(pgm)
EOF
    fi
    mp=$((6000 * 4000 / 1000000))
    if [[ ",$groups," == *",jpeg,"* ]]; then
        what="$(basename "$jpg") ($mp MP, q90) to PBM"
        add "halftone diffuse floyd-steinberg" \
            "$halftone convert $jpg -o $work/j-halftone.pbm --method diffuse"
        add "Pillow open→convert('L')→convert('1')" \
            "$pillow -c \"from PIL import Image; Image.open('$jpg').convert('L').convert('1').save('$work/j-pil.pbm')\""
        run_group "JPEG to PBM, Floyd–Steinberg"
    fi
    if [[ ",$groups," == *",thermal,"* ]]; then
        what="$(basename "$jpg") ($mp MP) to a 384-dot-wide PBM"
        add "halftone --preset thermal-203" \
            "$halftone convert $jpg -o $work/th-halftone.pbm --preset thermal-203 --format pbm"
        add "Pillow draft + Lanczos + convert('1')" \
            "$pillow -c \"from PIL import Image
im = Image.open('$jpg'); im.draft('L', (384, 256))
im = im.convert('L'); im = im.resize((384, im.height * 384 // im.width), Image.LANCZOS)
im.convert('1').save('$work/th-pil.pbm')\""
        has vipsthumbnail && add "vipsthumbnail -s 384 (no dithering)" \
            "vipsthumbnail $jpg -s 384 -o $PWD/$work/th-vips.png"
        run_group "JPEG to a thermal printer (203 dpi, 384 dots)"
    fi
    if [[ ",$groups," == *",rgb,"* ]]; then
        what="$(basename "$ppm") ($mp MP RGB) to PPM, and its grey PGM to PBM"
        add "halftone --color rgb, Floyd–Steinberg (PPM)" \
            "$halftone convert $ppm -o $work/rgb-halftone.ppm --method diffuse --color rgb"
        add "halftone grey, Floyd–Steinberg (PGM to PBM)" \
            "$halftone convert $pgm -o $work/grey-halftone.pbm --method diffuse"
        run_group "RGB against grey error diffusion"
    fi
    if [[ ",$groups," == *",palette,"* ]]; then
        what="$(basename "$ppm") ($mp MP RGB) to an 8-colour PNG"
        add "halftone --palette rgb-8 (Oklab nearest, linear error)" \
            "$halftone convert $ppm -o $work/pal-halftone.png --method diffuse --palette rgb-8"
        add "Pillow quantize(palette, FLOYDSTEINBERG)" \
            "$pillow -c \"from PIL import Image
pal = Image.new('P', (1, 1))
pal.putpalette([0,0,0, 255,0,0, 0,255,0, 0,0,255, 0,255,255, 255,0,255, 255,255,0, 255,255,255])
Image.open('$ppm').convert('RGB').quantize(palette=pal, dither=Image.Dither.FLOYDSTEINBERG).save('$work/pal-pil.png')\""
        run_group "Palette error diffusion (rgb-8)"
    fi
    what=""
fi
load=$(awk '{print $1, $2, $3}' /proc/loadavg 2>/dev/null || echo "?")
{
    echo "Machine: ${cpu:-unknown CPU}, $(nproc) CPUs, $(uname -sr); load average $load at the end;" \
        "$(date -u +%Y-%m-%d). Versions: halftone $("$halftone" --version 2>/dev/null | awk '{print $2}');" \
        "$(pamditherbw -version 2>&1 | awk '/Netpbm Version/ {print "Netpbm", $NF}' || true);" \
        "$(convert-im6.q16 -version 2>/dev/null | awk 'NR == 1 {print $2, $3}' || true);" \
        "Pillow $([ -n "$pillow" ] && $pillow -c 'import PIL; print(PIL.__version__)');" \
        "$(vips --version 2>/dev/null || true)."
    echo "Reproduce: scripts/peer-bench.sh"
} | tee -a "$table"
