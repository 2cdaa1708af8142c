"""Photo → CMYK plates: separated through the FOGRA39 press model, each plate screened
at its own angle; the plates as numpy arrays, the preview of the print as RGB, and the
plates as TIFF files with their inks' names."""
import sys

import numpy as np
from PIL import Image

import halftone

photo = sys.argv[1] if len(sys.argv) > 1 else "photo.jpg"
out = sys.argv[2] if len(sys.argv) > 2 else "plates.tif"

r = halftone.convert(photo, color="cmyk", method="screen", dpi=600, lpi=100, preview=True)
for ink, plate in r.plates.items():
    print(f"{ink:8} {np.mean(plate == 0):6.1%} ink")
Image.fromarray(r.preview).save(out.rsplit(".", 1)[0] + "-preview.png")
r.save(out)  # plates-cyan.tif … plates-black.tif
