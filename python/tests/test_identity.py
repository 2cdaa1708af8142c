"""Byte identity with the command line: the same options give the same file, byte for
byte, whether the input is a path, bytes, or the decoded pixels as a numpy array."""

import numpy as np
import pytest
from PIL import Image

import halftone

from conftest import assert_same_bytes, read

# (name, command-line flags, keyword arguments, extension, input)
CASES = [
    ("threshold", ["--method", "threshold", "--threshold", "40%"], dict(method="threshold", threshold="40%"), "pbm", "gray"),
    ("threshold-4", ["--method", "threshold", "--levels", "4"], dict(method="threshold", levels=4), "pgm", "gray"),
    ("pattern", ["--method", "pattern", "--mask", "seed-3x3"], dict(method="pattern", mask="seed-3x3"), "pbm", "gray"),
    ("pattern-expand", ["--method", "pattern", "--cell", "expand"], dict(method="pattern", cell="expand"), "png", "gray"),
    ("ordered", ["--method", "ordered", "--mask", "bayer-8"], dict(method="ordered", mask="bayer-8"), "pbm", "rgb"),
    ("ordered-4", ["--method", "ordered", "--mask", "blue-noise-64", "--levels", "4"], dict(method="ordered", mask="blue-noise-64", levels=4), "png", "gray"),
    ("diffuse", [], {}, "pbm", "rgb"),
    ("diffuse-kernels", ["--kernel", "jarvis-judice-ninke", "--no-serpentine"], dict(kernel="jarvis-judice-ninke", serpentine=False), "pbm", "gray"),
    ("diffuse-ostromoukhov", ["--kernel", "ostromoukhov"], dict(kernel="ostromoukhov"), "png", "rgb"),
    ("diffuse-tded", ["--kernel", "tded"], dict(kernel="tded"), "pbm", "gray"),
    ("diffuse-hysteresis", ["--hysteresis", "0.5"], dict(hysteresis=0.5), "pbm", "gray"),
    ("diffuse-rgb", ["--color", "rgb", "--levels", "3"], dict(color="rgb", levels=3), "png", "rgb"),
    ("dbs", ["--method", "dbs", "--passes", "4"], dict(method="dbs", passes=4), "pbm", "gray"),
    ("screen", ["--method", "screen", "--dpi", "300", "--lpi", "60", "--angle", "30", "--spot", "Ellipse"], dict(method="screen", dpi=300, lpi=60, angle=30, spot="Ellipse"), "pbm", "gray"),
    ("palette", ["--palette", "epaper-7"], dict(palette="epaper-7"), "png", "rgb"),
    ("palette-bmp", ["--palette", "eink-4"], dict(palette="eink-4"), "bmp", "rgb"),
    ("device", ["--device", "spectra6-7in3"], dict(device="spectra6-7in3"), "png", "rgb"),
    ("device-raw", ["--device", "bwry-3in97"], dict(device="bwry-3in97"), "raw", "rgb"),
    ("device-nominal", ["--device", "acep7-5in65", "--ink-colours", "nominal"], dict(device="acep7-5in65", ink_colours="nominal"), "png", "rgb"),
    ("resize", ["--fit", "60x50", "--rotate", "auto", "--levels", "4"], dict(fit="60x50", rotate="auto", levels=4), "png", "rgb"),
    ("tone", ["--gamma", "1.2", "--dot-gain", "15", "--invert"], dict(gamma=1.2, dot_gain=15, invert=True), "pbm", "gray"),
    ("alpha", ["--levels", "2"], dict(levels=2), "pbm", "rgba"),
    ("tiff-g4", ["--compression", "g4", "--dpi", "200"], dict(compression="g4", dpi=200), "tif", "gray"),
    ("pdf", ["--dpi", "300", "--page", "a4"], dict(dpi=300, page="a4"), "pdf", "gray"),
    ("pdf-g4", ["--compression", "g4"], dict(compression="g4"), "pdf", "rgb"),
    ("ps", ["--dpi", "300"], dict(dpi=300), "ps", "gray"),
    ("pcl", ["--dpi", "300", "--page", "letter"], dict(dpi=300, page="letter"), "pcl", "rgb"),
    ("escpos", ["--cut", "--band-rows", "24"], dict(cut=True, band_rows=24), "escpos", "gray"),
    ("zpl", [], {}, "zpl", "gray"),
    ("zpl-z64", ["--zpl-encoding", "z64"], dict(zpl_encoding="z64"), "zpl", "rgb"),
    ("preset", ["--preset", "thermal-203"], dict(preset="thermal-203"), "escpos", "rgb"),
    ("preset-override", ["--preset", "thermal-203", "--kernel", "stucki"], dict(preset="thermal-203", kernel="stucki"), "escpos", "rgb"),
]


@pytest.mark.parametrize("name,flags,kw,ext,src", CASES, ids=[c[0] for c in CASES])
def test_same_bytes_as_cli(cli, images, tmp_path, name, flags, kw, ext, src):
    assert_same_bytes(cli, images, tmp_path, name, flags, kw, ext, src)


def test_gray_array_without_copy_matches_copy(images):
    """The borrowed road (C-contiguous uint8 grey) and the copying road agree."""
    a = np.asarray(Image.open(images["gray"]))
    assert a.flags.c_contiguous and a.dtype == np.uint8
    strided = np.asfortranarray(a)
    assert not strided.flags.c_contiguous
    for kw in [{}, dict(palette="epaper-7"), dict(method="screen", dpi=300), dict(color="rgb", levels=3)]:
        x = halftone.convert(a, **kw)
        y = halftone.convert(strided, **kw)
        assert x.encode("png") == y.encode("png"), kw
        assert np.array_equal(x.array, y.array)


@pytest.mark.parametrize("ext", ["tif", "png", "pbm", "pdf"])
def test_cmyk_plates_same_bytes(cli, images, tmp_path, ext):
    flags = ["--color", "cmyk", "--method", "screen", "--dpi", "300", "--lpi", "50"]
    kw = dict(color="cmyk", method="screen", dpi=300, lpi=50, preview=True)
    cli("convert", images["rgb"], "-o", tmp_path / f"cli.{ext}", *flags, "--preview", tmp_path / "prev.png")
    r = halftone.convert(images["rgb"], **kw)
    r.save(tmp_path / f"py.{ext}")
    if ext == "pdf":
        assert read(tmp_path / "py.pdf") == read(tmp_path / "cli.pdf")
        assert r.encode("pdf") == read(tmp_path / "cli.pdf")
    else:
        for ink in halftone.INKS:
            want = read(tmp_path / f"cli-{ink}.{ext}")
            assert read(tmp_path / f"py-{ink}.{ext}") == want, ink
            assert r.encode(ext, plate=ink) == want, ink
    # Plates as arrays, the preview as RGB, as the command line's preview PNG.
    assert r.array.shape == (4, r.height, r.width)
    assert set(r.plates) == set(halftone.INKS)
    prev = np.asarray(Image.open(tmp_path / "prev.png").convert("RGB"))
    assert np.array_equal(r.preview, prev)


def test_array_matches_pgm_levels(cli, images, tmp_path):
    """.array holds the levels the device-level PGM holds."""
    cli("convert", images["gray"], "-o", tmp_path / "x.pgm", "--levels", "4", "--device-levels")
    # The raw device levels, maxval levels - 1 (Pillow would scale them up to 255).
    data = read(tmp_path / "x.pgm")
    magic, w, h, maxval, raw = data.split(maxsplit=4)
    assert (magic, maxval) == (b"P5", b"3")
    want = np.frombuffer(raw, dtype=np.uint8).reshape(int(h), int(w))
    r = halftone.convert(images["gray"], levels=4)
    assert np.array_equal(r.array, want)
    assert r.array.max() == 3


def test_palette_indices(images):
    r = halftone.convert(images["rgb"], palette="epaper-7")
    assert r.kind == "palette" and len(r.palette) == 7
    assert r.array.shape == (r.height, r.width)
    assert r.array.max() < 7
    assert r.to_pil().mode == "P"
    rgb = r.to_rgb()
    assert rgb.shape == (r.height, r.width, 3)


def test_compare_same_figures(cli, images, tmp_path):
    import json

    cli("convert", images["rgb"], "-o", tmp_path / "h.pbm")
    want = json.loads(cli("compare", images["rgb"], tmp_path / "h.pbm", "--json", "--dpi", "200", "--distance", "10"))["quality"]
    got = halftone.compare(images["rgb"], tmp_path / "h.pbm", dpi=200, distance=10)
    for k in ["hvs_psnr_db", "hvs_mse", "tone_bias", "lstar_rms", "plain_psnr_db"]:
        assert got[k] == want[k], k
    # A result in memory gives the same figures as its file.
    r = halftone.convert(images["rgb"])
    mem = halftone.compare(images["rgb"], r, dpi=200, distance=10)
    assert mem["hvs_psnr_db"] == pytest.approx(want["hvs_psnr_db"], rel=1e-9)
