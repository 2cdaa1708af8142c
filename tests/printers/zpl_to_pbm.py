"""Decodes a ZPL label with zebrafy (PyPI) into a P4 PBM on stdout: every ^GF field
decoded by zebrafy, placed at its ^FO origin on a ^PW x ^LL canvas (1 = black)."""
import re
import sys

from PIL import Image
from zebrafy import ZebrafyZPL

zpl = open(sys.argv[1]).read()
label = zpl.split("^XZ")[int(sys.argv[2]) if len(sys.argv) > 2 else 0]
width = int(re.search(r"\^PW(\d+)", label).group(1))
length = int(re.search(r"\^LL(\d+)", label).group(1))
origins = [(int(x), int(y)) for x, y in re.findall(r"\^FO(\d+),(\d+)\^GF", label)]
fields = ZebrafyZPL(label + "^XZ").to_images()
assert len(fields) == len(origins), (len(fields), len(origins))
canvas = Image.new("1", (width, length), 1)
for (x, y), im in zip(origins, fields):
    canvas.paste(im.convert("1").crop((0, 0, min(im.width, width - x), im.height)), (x, y))
sys.stderr.write(f"fields={len(fields)}\n")
sys.stdout.buffer.write(b"P4\n%d %d\n" % (width, length))
# PIL's mode "1" packs 1 = white; PBM wants 1 = black.
sys.stdout.buffer.write(bytes(b ^ 0xFF for b in canvas.tobytes()))
