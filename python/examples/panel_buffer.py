"""Photo → a Spectra 6 panel's own buffer: fitted into its 800x480 in linear light and
padded with white to exactly that size, mapped to its six measured inks (perceptual
intent), Floyd–Steinberg; the PNG shows what the
panel will show, the .bin holds the 4-bit ink codes its firmware takes; then the colour
error a viewer of the panel sees, as `halftone compare --device` measures it."""
import sys

from PIL import Image

import halftone

photo = sys.argv[1] if len(sys.argv) > 1 else "photo.jpg"
out = sys.argv[2] if len(sys.argv) > 2 else "frame"
panel = "spectra6-7in3-v2"

r = halftone.convert(photo, device=panel)  # 800x480: fitted, padded with white; perceptual
r.save(out + ".png")  # what the panel shows (the inks' measured colours)
r.save(out + ".bin")  # the 4-bit ink codes its firmware takes; .h: a C header

# How it looks on the panel: the original and the halftone at the same size (a size given
# keeps the picture's own, instead of fitting it to the panel).
small = Image.open(photo).convert("RGB")
small.thumbnail((800, 480))
q = halftone.compare(small, halftone.convert(small, device=panel, width=small.width), device=panel)
print(f"{out}.bin: {r.width}x{r.height}; {q['de2000']:.2f} CIEDE2000, lightness {q['lightness_ratio']:.3f}")
