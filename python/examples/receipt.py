"""Photo → receipt printer bytes: the thermal-203 preset (384 dots wide, Atkinson,
dot-gain compensation), encoded as ESC/POS raster with a cut. Write the bytes to the
printer (/dev/usb/lp0, a socket, python-escpos's `_raw`) or to a file."""
import sys

import halftone

photo = sys.argv[1] if len(sys.argv) > 1 else "photo.jpg"
out = sys.argv[2] if len(sys.argv) > 2 else "receipt.escpos"

data = halftone.convert(photo, preset="thermal-203", cut=True).encode("escpos")
with open(out, "wb") as printer:
    printer.write(data)
print(f"{out}: {len(data)} bytes of ESC/POS")
