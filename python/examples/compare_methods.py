"""Which method looks closest to the photo at reading distance? The HVS-filtered PSNR
and tone bias of `halftone compare` for a few methods."""
import sys

import halftone

photo = sys.argv[1] if len(sys.argv) > 1 else "photo.jpg"

for name, kw in {
    "floyd-steinberg": {},
    "atkinson": dict(kernel="atkinson"),
    "ordered bayer-8": dict(method="ordered", mask="bayer-8"),
    "blue noise": dict(method="ordered", mask="blue-noise-64"),
    "screen 85 lpi": dict(method="screen", dpi=300, lpi=85),
}.items():
    q = halftone.compare(photo, halftone.convert(photo, **kw), dpi=300, distance=12)
    print(f"{name:18} HVS-PSNR {q['hvs_psnr_db']:6.2f} dB  tone bias {q['tone_bias']:+.4f}")
