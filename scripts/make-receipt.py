#!/usr/bin/env python3
"""Draws samples/receipt/receipt.png: a 58 mm receipt (384 dots at 203 dpi) with
anti-aliased text, rules, an EAN-13 barcode and a photograph (samples/raytrace.png), the
mix that `--content auto` is for. Needs Pillow and the DejaVu fonts (Debian:
python3-pil fonts-dejavu-core).

    python3 scripts/make-receipt.py      # from the repository root
"""
from PIL import Image, ImageDraw, ImageFont

W = 384
FONT = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"
BOLD = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf"

# EAN-13 digit patterns (GS1 General Specifications, 5.2.1.2): L and G codes for the
# left half (chosen by the first digit), R codes for the right half.
L = ["0001101", "0011001", "0010011", "0111101", "0100011",
     "0110001", "0101111", "0111011", "0110111", "0001011"]
G = ["".join("1" if c == "0" else "0" for c in reversed(p)) for p in L]
R = ["".join("1" if c == "0" else "0" for c in p) for p in L]
PARITY = ["LLLLLL", "LLGLGG", "LLGGLG", "LLGGGL", "LGLLGG",
          "LGGLLG", "LGGGLL", "LGLGLG", "LGLGGL", "LGGLGL"]


def ean13(digits12):
    d = [int(c) for c in digits12]
    check = (10 - sum(x * (3 if i % 2 else 1) for i, x in enumerate(d)) % 10) % 10
    d.append(check)
    bits = "101"
    for i, x in enumerate(d[1:7]):
        bits += (L if PARITY[d[0]][i] == "L" else G)[x]
    bits += "01010"
    for x in d[7:]:
        bits += R[x]
    bits += "101"
    return "".join(map(str, d)), bits


def main():
    photo = Image.open("samples/raytrace.png").convert("L")
    photo = photo.resize((W - 32, round(photo.height * (W - 32) / photo.width)), Image.LANCZOS)
    h = 700 + photo.height
    im = Image.new("L", (W, h), 255)
    dr = ImageDraw.Draw(im)
    big = ImageFont.truetype(BOLD, 30)
    med = ImageFont.truetype(FONT, 18)
    small = ImageFont.truetype(FONT, 14)
    y = 12
    dr.text((W // 2, y), "HALFTONE CAFÉ", font=big, fill=0, anchor="mt")
    y += 42
    dr.text((W // 2, y), "12 Screen Street, Dotsville", font=small, fill=0, anchor="mt")
    y += 26
    dr.line((8, y, W - 8, y), fill=0, width=2)
    y += 12
    for item, price in [("Flat white", "3.40"), ("Croissant", "2.10"),
                        ("Dithered toast", "4.75"), ("Error diffusion", "0.99")]:
        dr.text((16, y), item, font=med, fill=0)
        dr.text((W - 16, y), price, font=med, fill=0, anchor="ra")
        y += 26
    dr.line((8, y + 4, W - 8, y + 4), fill=0, width=1)
    y += 14
    dr.text((16, y), "TOTAL", font=big, fill=0)
    dr.text((W - 16, y), "11.24", font=big, fill=0, anchor="ra")
    y += 48
    im.paste(photo, (16, y))
    y += photo.height + 14
    dr.text((W // 2, y), "Today's special: ray-traced spheres", font=small, fill=90, anchor="mt")
    y += 28
    number, bits = ean13("590123412345")
    module = 3
    x0 = (W - len(bits) * module) // 2
    for i, b in enumerate(bits):
        if b == "1":
            dr.rectangle((x0 + i * module, y, x0 + (i + 1) * module - 1, y + 90), fill=0)
    y += 96
    dr.text((W // 2, y), number, font=med, fill=0, anchor="mt")
    y += 34
    # A light grey tint box: continuous tone that is not a photo.
    dr.rectangle((16, y, W - 16, y + 50), fill=200)
    dr.text((W // 2, y + 25), "Thank you!", font=big, fill=0, anchor="mm")
    y += 70
    im.crop((0, 0, W, y)).save("samples/receipt/receipt.png")


if __name__ == "__main__":
    main()
