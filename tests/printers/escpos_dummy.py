"""Encodes a PBM (argv[1]) with python-escpos's Dummy printer (GS v 0 raster, 960-row
fragments) and writes the bytes it would send to argv[2] (its stdout carries notes)."""
import sys

from escpos.printer import Dummy
from PIL import Image

im = Image.open(sys.argv[1]).convert("1")
p = Dummy()
p.image(im, impl="bitImageRaster", fragment_height=960)
with open(sys.argv[2], "wb") as f:
    f.write(p.output)
