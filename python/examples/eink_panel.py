"""Photo → a 7-colour e-paper panel (800x480): resized in linear light, turned to fit,
diffused to the panel's measured palette; the PNG holds palette indices the panel driver
can send as they are."""
import sys

import halftone

photo = sys.argv[1] if len(sys.argv) > 1 else "photo.jpg"
out = sys.argv[2] if len(sys.argv) > 2 else "panel.png"

r = halftone.convert(photo, fit="800x480", rotate="auto", palette="epaper-7")
r.save(out)
print(f"{out}: {r.width}x{r.height}, colour indices {r.array.min()}..{r.array.max()} of {len(r.palette)}")
