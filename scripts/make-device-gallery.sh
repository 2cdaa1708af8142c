#!/usr/bin/env bash
# The README's device gallery: a photo, the same photo diffused to the panel's nominal
# palette (pure RGB typed in, no mapping), and rendered for the measured panel (--device,
# perceptual intent), both shown in the panel's measured colours (200 pixels high, at the
# panel's own pixels), for a 6-colour, a black/white/red and a 4-grey panel. Needs the
# binary and Pillow (python3-pil).
set -euo pipefail
cd "$(dirname "$0")/.."
B=${HALFTONE:-target/release/halftone}
PHOTO=${1:-/usr/lib/python3/dist-packages/skimage/data/astronaut.png}
T=$(mktemp -d)
for d in spectra6-7in3-v2 hanshow-bwr grey4-4in2; do
  $B convert "$PHOTO" -o "$T/$d-device.png" --device "$d" --height 200
  size=$(python3 -c "from PIL import Image; print('%dx%d' % Image.open('$T/$d-device.png').size)")
  $B devices show "$d" | python3 -c '
import sys, tomllib
d = tomllib.loads(sys.stdin.read())
print("\n".join(i["nominal"] for i in d["ink"]))' > "$T/$d.hex"
  $B convert "$PHOTO" -o "$T/$d-nominal.png" --palette "$T/$d.hex" --width "${size%x*}"
  $B convert "$PHOTO" -o "$T/$d-photo.png" --method threshold --color rgb --levels 256 --width "${size%x*}"
done
python3 - "$T" <<'PY'
import sys, tomllib, subprocess
from PIL import Image
t = sys.argv[1]
rows = []
for d in ["spectra6-7in3-v2", "hanshow-bwr", "grey4-4in2"]:
    prof = tomllib.loads(subprocess.run(["target/release/halftone", "devices", "show", d],
                                        capture_output=True, text=True).stdout)
    shown = [i.get("measured", i["nominal"]) for i in prof["ink"]]
    shown = [tuple(int(h.lstrip("#")[k:k + 2], 16) for k in (0, 2, 4)) for h in shown]
    nominal = Image.open(f"{t}/{d}-nominal.png")
    # The nominal palette's indices are the inks': shown as the panel shows them.
    nominal.putpalette([c for rgb in shown for c in rgb])
    ims = [Image.open(f"{t}/{d}-photo.png").convert("RGB"), nominal.convert("RGB"),
           Image.open(f"{t}/{d}-device.png").convert("RGB")]
    h = 200
    ims = [i.resize((round(i.width * h / i.height), h), Image.NEAREST) for i in ims]
    row = Image.new("RGB", (sum(i.width for i in ims) + 8 * 2, h), "white")
    x = 0
    for i in ims:
        row.paste(i, (x, 0))
        x += i.width + 8
    rows.append(row)
sheet = Image.new("RGB", (max(r.width for r in rows), sum(r.height for r in rows) + 8 * 2), "white")
y = 0
for r in rows:
    sheet.paste(r, (0, y))
    y += r.height + 8
sheet.save("assets/devices/gallery.png", optimize=True)
PY
rm -rf "$T"
echo "assets/devices/gallery.png"
