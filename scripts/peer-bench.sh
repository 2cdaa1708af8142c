#!/usr/bin/env bash
# Ordered dithering against its peers, whole process, one machine, one run:
# a 24-megapixel grey PGM to a PBM with an 8x8 Bayer matrix.
#
#   halftone convert in.pgm -o out.pbm --method ordered --mask bayer-8
#   pamditherbw -dither8 in.pgm > out.pbm          (netpbm)
#   convert-im6.q16 in.pgm -ordered-dither o8x8 out.pbm   (ImageMagick 6)
#
# Usage: scripts/peer-bench.sh [-i INPUT.pgm] [-o TABLE.md] [-r RUNS] [--no-build]
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
while [ $# -gt 0 ]; do
    case "$1" in
        -i) input="$2"; shift 2 ;;
        -o) table="$2"; shift 2 ;;
        -r) runs="$2"; shift 2 ;;
        --no-build) build=0; shift ;;
        -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
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
halftone=target/release/halftone

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

# --- commands --------------------------------------------------------------------------
names=()
cmds=()
if [ -x "$halftone" ] && "$halftone" convert "$input" -o "$work/out-halftone.pbm" \
        --method ordered --mask bayer-8 >/dev/null 2>"$work/halftone.err"; then
    names+=("halftone")
    cmds+=("$halftone convert $input -o $work/out-halftone.pbm --method ordered --mask bayer-8")
else
    note "skipping halftone: $(head -c 300 "$work/halftone.err" 2>/dev/null || echo 'not built')"
fi
if command -v pamditherbw >/dev/null; then
    # pamditherbw writes a PAM of one byte a pixel; pamtopnm makes it the same PBM.
    names+=("netpbm pamditherbw")
    cmds+=("pamditherbw -dither8 $input > $work/out-netpbm.pam")
    if command -v pamtopnm >/dev/null; then
        names+=("netpbm pamditherbw + pamtopnm")
        cmds+=("pamditherbw -dither8 $input | pamtopnm > $work/out-netpbm.pbm")
    fi
else
    note "skipping netpbm: pamditherbw not found (Debian package netpbm)"
fi
if command -v convert-im6.q16 >/dev/null; then
    names+=("ImageMagick 6")
    cmds+=("convert-im6.q16 $input -ordered-dither o8x8 $work/out-imagemagick.pbm")
else
    note "skipping ImageMagick: convert-im6.q16 not found (Debian package imagemagick-6.q16)"
fi
[ ${#cmds[@]} -gt 0 ] || { note "nothing to run"; exit 1; }

# --- timing ----------------------------------------------------------------------------
hf_args=(--warmup 1 --runs "$runs" --export-json "$work/hyperfine.json" --style basic)
for i in "${!cmds[@]}"; do
    hf_args+=(--command-name "${names[$i]}" "${cmds[$i]}")
done
hyperfine "${hf_args[@]}" >&2

# Peak resident memory, one run each.
rss=()
for i in "${!cmds[@]}"; do
    if [ -x /usr/bin/time ]; then
        kb=$(/usr/bin/time -v bash -c "${cmds[$i]}" 2>&1 >/dev/null |
            awk -F': ' '/Maximum resident set size/ {print $2}')
        rss+=("$(awk -v k="$kb" 'BEGIN { printf "%.1f MiB", k / 1024 }')")
    else
        rss+=("n/a")
    fi
done

# --- table -----------------------------------------------------------------------------
pixels=$(head -c 64 "$input" | tr '\n' ' ' | awk '{ print $2 * $3 }')
input_mib=$(du -m "$input" | cut -f1)
cpu=$(lscpu 2>/dev/null | awk -F': *' '/Model name/ {print $2; exit}')
{
    echo "Ordered dithering, 8x8 Bayer, $(basename "$input") ($((pixels / 1000000)) MP grey PGM," \
        "$input_mib MiB) to PBM, whole process: mean ± σ of $runs runs after 1 warm-up (hyperfine)."
    load=$(awk '{print $1, $2, $3}' /proc/loadavg 2>/dev/null || echo "?")
    echo "Machine: ${cpu:-unknown CPU}, $(nproc) CPUs, $(uname -sr); load average $load" \
        "at the end; $(date -u +%Y-%m-%d)."
    echo
    echo "| command | mean ± σ | relative | peak RSS |"
    echo "|---|---|---|---|"
    python_json=$(cat "$work/hyperfine.json")
    i=0
    # Parse the JSON with awk-friendly jq if present, otherwise with python3.
    if command -v jq >/dev/null; then
        mapfile -t rows < <(jq -r '.results[] | "\(.mean) \(.stddev)"' <<<"$python_json")
    else
        mapfile -t rows < <(python3 -c 'import json,sys
for r in json.load(sys.stdin)["results"]: print(r["mean"], r["stddev"] or 0)' <<<"$python_json")
    fi
    fastest=$(printf '%s\n' "${rows[@]}" | awk 'NR == 1 || $1 < m { m = $1 } END { print m }')
    for row in "${rows[@]}"; do
        read -r mean sd <<<"$row"
        awk -v n="${names[$i]}" -v m="$mean" -v s="$sd" -v f="$fastest" -v r="${rss[$i]}" \
            'BEGIN { printf "| %s | %.1f ms ± %.1f | %.1f× | %s |\n", n, m * 1000, s * 1000, m / f, r }'
        i=$((i + 1))
    done
    echo
    echo "Versions: halftone $("$halftone" --version 2>/dev/null | awk '{print $2}');" \
        "$(pamditherbw -version 2>&1 | awk '/Netpbm Version/ {print "Netpbm", $NF}' || true);" \
        "$(convert-im6.q16 -version 2>/dev/null | awk 'NR == 1 {print $2, $3}' || true)."
    echo "Reproduce: scripts/peer-bench.sh"
} | tee "$table"
