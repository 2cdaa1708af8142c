#!/usr/bin/env bash
# The constant-memory proof: a 1.5-gigapixel photo-like PGM to PBM with Floyd-Steinberg and
# with ordered dithering, streamed, against the in-memory path and netpbm.
#
#   1. Streams a 40000x37500 photo-like PGM to disk (examples/photo_pgm.rs; never in memory).
#   2. Converts it with --method diffuse and --method ordered (automatic budget: it streams),
#      timing each with /usr/bin/time -v: wall time, peak RSS.
#   3. On a smaller image (12000x8000, 96 MP) that fits in memory: the whole-image path
#      (--max-memory 4G) and the streamed path (--max-memory 32M), same bytes (cmp) and
#      their throughput.
#   4. netpbm pamditherbw -fs on the same gigapixel file (apt netpbm), for time and memory.
#
# Usage: scripts/gigapixel.sh [-d DIR] [--no-build] [--no-netpbm] [-W WIDTH -H HEIGHT]
# DIR (default /work/big, else /tmp) holds the big files; they are deleted at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
dir=/work/big
[ -d /work ] || dir=/tmp/halftone-big
build=1
netpbm=1
W=40000
H=37500
while [ $# -gt 0 ]; do
    case "$1" in
        -d) dir="$2"; shift 2 ;;
        -W) W="$2"; shift 2 ;;
        -H) H="$2"; shift 2 ;;
        --no-build) build=0; shift ;;
        --no-netpbm) netpbm=0; shift ;;
        -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
        *) echo "gigapixel: unknown argument $1" >&2; exit 2 ;;
    esac
done
target=${CARGO_TARGET_DIR:-target}
if [ "$build" = 1 ]; then
    cargo build --profile bench --bin halftone --example photo_pgm >&2
fi
bin="$target/release/halftone"
gen="$target/release/examples/photo_pgm"
mkdir -p "$dir"
trap 'rm -f "$dir"/giga.pgm "$dir"/giga-*.pbm "$dir"/mid.pgm "$dir"/mid-*.pbm' EXIT
px=$((W * H))
mpx() { awk -v p="$1" -v s="$2" 'BEGIN { printf "%.0f", p / s / 1e6 }'; }
# Runs a command under /usr/bin/time -v; prints "seconds peak-MiB".
measure() {
    local log="$dir/time.log"
    if ! /usr/bin/time -v "$@" 2>"$log" >/dev/null; then
        echo "gigapixel: failed: $*" >&2
        cat "$log" >&2
        exit 1
    fi
    local wall rss
    wall=$(awk -F': ' '/Elapsed \(wall clock\)/ {n = split($2, t, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + t[i]; print s}' "$log")
    rss=$(awk -F': ' '/Maximum resident set size/ {printf "%.1f", $2 / 1024}' "$log")
    echo "$wall $rss"
}

echo "generating ${W}x${H} ($((px / 1000000)) MP) in $dir" >&2
"$gen" "$W" "$H" > "$dir/giga.pgm"
echo "| job | time | peak RSS | throughput |"
echo "|---|---|---|---|"
for m in "diffuse" "ordered --mask bayer-8"; do
    # shellcheck disable=SC2086
    read -r s r < <(measure "$bin" convert "$dir/giga.pgm" -o "$dir/giga-${m%% *}.pbm" \
        --method $m --max-pixels 4000000000)
    bytes=$(stat -c %s "$dir/giga-${m%% *}.pbm")
    echo "| $((px / 1000000)) MP, --method $m, streamed (automatic budget), $bytes bytes out | $s s | $r MiB | $(mpx $px "$s") MP/s |"
done

"$gen" 12000 8000 > "$dir/mid.pgm"
mid=$((12000 * 8000))
for m in "diffuse" "ordered --mask bayer-8"; do
    tag=${m%% *}
    # shellcheck disable=SC2086
    read -r s1 r1 < <(measure "$bin" convert "$dir/mid.pgm" -o "$dir/mid-$tag-whole.pbm" --method $m --max-memory 4G)
    # shellcheck disable=SC2086
    read -r s2 r2 < <(measure "$bin" convert "$dir/mid.pgm" -o "$dir/mid-$tag-stream.pbm" --method $m --max-memory 32M)
    same=differ
    cmp -s "$dir/mid-$tag-whole.pbm" "$dir/mid-$tag-stream.pbm" && same="same bytes"
    echo "| 96 MP, --method $m, whole image (--max-memory 4G) | $s1 s | $r1 MiB | $(mpx $mid "$s1") MP/s |"
    echo "| 96 MP, --method $m, streamed (--max-memory 32M), $same | $s2 s | $r2 MiB | $(mpx $mid "$s2") MP/s |"
done

if [ "$netpbm" = 1 ] && command -v pamditherbw >/dev/null; then
    read -r s r < <(measure pamditherbw -fs "$dir/giga.pgm")
    echo "| $((px / 1000000)) MP, netpbm pamditherbw -fs | $s s | $r MiB | $(mpx $px "$s") MP/s |"
fi
