"""The Python front door: inputs, listings, results, threads and errors."""

import io
import struct
import threading
import zlib

import numpy as np
import pytest

import halftone


def ramp(h=32, w=64, dtype=np.uint8):
    top = np.iinfo(dtype).max if dtype != np.float32 else 1.0
    row = np.linspace(0, top, w)
    return np.tile(row, (h, 1)).astype(dtype)


def test_listings():
    assert halftone.methods() == ["threshold", "pattern", "ordered", "diffuse", "dbs", "screen"]
    assert "floyd-steinberg" in halftone.kernels() and "atkinson" in halftone.kernels()
    assert "epaper-7" in halftone.palettes()
    assert "bayer-8" in halftone.masks()
    assert "thermal-203" in halftone.presets()
    assert "Round" in halftone.spots()
    assert "escpos" in halftone.formats()


def test_defaults_bilevel_grey():
    r = halftone.convert(ramp())
    assert (r.width, r.height, r.levels, r.kind) == (64, 32, 2, "gray")
    assert r.array.shape == (32, 64) and r.array.dtype == np.uint8
    assert set(np.unique(r.array)) <= {0, 1}
    # Light in linear light: the left of a sRGB ramp is darker than its right.
    assert r.array[:, :8].mean() < r.array[:, -8:].mean()
    assert r.to_pil().mode == "1"
    assert r.encode("pbm").startswith(b"P4\n64 32\n")


def test_float_and_uint16_and_linear():
    f = ramp(dtype=np.float32)
    u16 = np.rint(f.astype(np.float64) * 65535).astype(np.uint16)
    a = halftone.convert(f).array
    b = halftone.convert(u16).array
    assert np.array_equal(a, b)
    # Linear data: half the light is 50% ink; as sRGB codes, 0.5 is ~21% of the light.
    half = np.full((64, 64), 0.5, dtype=np.float64)
    lin = halftone.convert(half, linear=True).array.mean()
    srgb = halftone.convert(half).array.mean()
    assert abs(lin - 0.5) < 0.02
    assert abs(srgb - 0.214) < 0.02


def test_rgba_composited_on_white():
    a = np.zeros((16, 16, 4), dtype=np.uint8)  # black, fully transparent
    assert halftone.convert(a).array.min() == 1  # all paper


def test_result_is_read_only():
    r = halftone.convert(ramp())
    with pytest.raises(ValueError):
        r.array[0, 0] = 1


@pytest.mark.parametrize(
    "bad,exc,text",
    [
        (np.zeros((8, 8), dtype=np.int32), TypeError, "uint8, uint16 or float"),
        (np.zeros((8, 8), dtype=np.complex64), TypeError, "uint8, uint16 or float"),
        (np.zeros((8, 8, 5), dtype=np.uint8), ValueError, "HxWx4"),
        (np.zeros((2, 8, 8, 3), dtype=np.uint8), ValueError, "shape"),
        (np.zeros(8, dtype=np.uint8), ValueError, "shape"),
        (np.zeros((0, 8), dtype=np.uint8), ValueError, "empty"),
        (np.zeros((8, 0, 3), dtype=np.uint16), ValueError, "empty"),
        (np.full((4, 4), np.nan), ValueError, "NaN"),
        (np.full((4, 4), 2.0), ValueError, "from 0 to 1"),
        (b"not an image", ValueError, "<bytes>"),
        (b"", ValueError, "empty"),
        (12, TypeError, "expected a path"),
        ("/nonexistent/photo.png", OSError, "/nonexistent/photo.png"),
    ],
)
def test_bad_input(bad, exc, text):
    with pytest.raises(exc, match=text if text != "NaN" else "NaN"):
        halftone.convert(bad)


def test_closed_file(tmp_path):
    p = tmp_path / "x.png"
    from PIL import Image

    Image.fromarray(ramp()).save(p)
    f = open(p, "rb")
    assert halftone.convert(f).width == 64
    f = open(p, "rb")
    f.close()
    with pytest.raises(ValueError, match="closed"):
        halftone.convert(f)


def png_header_only(width, height):
    """A PNG that declares width x height pixels and holds almost nothing."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 10)) + chunk(b"IEND", b"")


def test_huge_declared_size():
    with pytest.raises(ValueError, match="over the limit"):
        halftone.convert(png_header_only(100000, 100000))
    with pytest.raises(ValueError, match="over the limit"):
        halftone.convert(png_header_only(1000, 1000), max_pixels=1000)


@pytest.mark.parametrize(
    "kw,exc,text",
    [
        (dict(method="difuse"), ValueError, "method=difuse: .*diffuse"),
        (dict(levels=1), ValueError, "levels"),
        (dict(levels=-3), ValueError, "levels must be from 2 to 256"),
        (dict(dot_gain=60), ValueError, "dot_gain=60"),
        (dict(gamma=0), ValueError, "gamma=0"),
        (dict(kernel="nope"), ValueError, "nope"),
        (dict(palette="nope"), ValueError, "nope"),
        (dict(method="dbs", palette="auto:8"), ValueError, "palette=auto:8: a palette made from the image works with methods diffuse and ordered"),
        (dict(palette="auto:300"), ValueError, "palette=auto:300: an automatic palette has 2 to 256"),
        (dict(preset="thermal-2O3"), ValueError, "thermal-203"),
        (dict(fit="wide"), ValueError, "fit=wide"),
        (dict(threshold="half"), ValueError, "threshold=half"),
        (dict(method="screen", lpi="fast"), ValueError, "lpi=fast: must be a number"),
        (dict(spot="blob", method="screen"), ValueError, "blob"),
        (dict(colour="rgb"), TypeError, "colour"),
        (dict(serpentine="yes"), TypeError, "serpentine"),
    ],
)
def test_bad_options(kw, exc, text):
    with pytest.raises(exc, match=text):
        halftone.convert(ramp(), **kw)


def test_bad_formats(tmp_path):
    r = halftone.convert(ramp())
    with pytest.raises(ValueError, match="format=jpg"):
        r.encode("jpg")
    with pytest.raises(ValueError, match="no format"):
        r.save(tmp_path / "x.unknown")
    with pytest.raises(OSError):
        r.save(tmp_path / "missing-dir" / "x.pbm")
    c = halftone.convert(np.zeros((8, 8, 3), np.uint8), color="cmyk")
    with pytest.raises(ValueError, match="plate"):
        c.encode("png")


def test_preset_fields_apply_where_not_given():
    img = np.tile(np.linspace(0, 255, 800).astype(np.uint8), (100, 1))
    r = halftone.convert(img, preset="thermal-203")
    assert r.width == 384  # the preset's width
    r = halftone.convert(img, preset="thermal-203", width=200)
    assert r.width == 200


def test_threads_give_identical_results():
    img = (np.random.default_rng(1).random((300, 400)) * 255).astype(np.uint8)
    want = halftone.convert(img, kernel="stucki").encode("png")
    out = [None] * 8

    def work(i):
        out[i] = halftone.convert(img, kernel="stucki").encode("png")

    ts = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert all(o == want for o in out)


def test_threads_keyword_keeps_the_bytes():
    """threads= runs a call's parallel work (palette bands, device bands, DBS) on that many
    threads: the bytes do not change; bad values are clear errors."""
    rng = np.random.default_rng(2)
    rgb = (rng.random((300, 260, 3)) * 255).astype(np.uint8)
    for kw in [dict(palette="epaper-7"), dict(device="spectra6-7in3-v2", width=260)]:
        want = halftone.convert(rgb, **kw).encode("png")
        for n in [1, 2, 3]:
            assert halftone.convert(rgb, threads=n, **kw).encode("png") == want, (kw, n)
        assert halftone.convert_to_bytes(rgb, "png", threads=1, **kw) == halftone.convert_to_bytes(rgb, "png", **kw)
    with pytest.raises(ValueError, match=r"^threads=0: expected a number of threads from 1 to 1024$"):
        halftone.convert(rgb, threads=0)
    with pytest.raises(TypeError, match="threads: expected an integer"):
        halftone.convert(rgb, threads="two")
    with pytest.raises(TypeError, match="not a bool"):
        halftone.convert(rgb, threads=True)


def test_docstrings_and_repr():
    assert "linear" in halftone.convert.__doc__
    r = halftone.convert(ramp())
    assert "64x32" in repr(r)
    assert r._repr_png_().startswith(b"\x89PNG")


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("channels", [0, 3, 4])
def test_memory_order_does_not_matter(dtype, channels):
    """Fortran-ordered and strided views give the halftone of the same pixels."""
    rng = np.random.default_rng(7)
    shape = (40, 56) if channels == 0 else (40, 56, channels)
    a = rng.random(shape)
    if dtype != np.float32:
        a = (a * np.iinfo(dtype).max).astype(dtype)
    else:
        a = a.astype(dtype)
    want = halftone.convert(a, kernel="stucki").encode("pgm")
    assert halftone.convert(np.asfortranarray(a), kernel="stucki").encode("pgm") == want
    wide = np.concatenate([a, a], axis=1)[:, ::2]
    assert halftone.convert(np.ascontiguousarray(wide), kernel="stucki").encode("pgm") == halftone.convert(wide, kernel="stucki").encode("pgm")
