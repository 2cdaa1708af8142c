"""E-paper panels from Python: the same bytes as `halftone convert --device` for every
rendering intent and steering option, DBS and ordered dithering to the inks, automatic
palettes and the panels' own buffer encodings; the figures of `halftone compare --device`;
the profiles `halftone devices list` lists; and the command line's messages for bad values."""

import io
import json
import warnings
import math
import re

import numpy as np
import pytest
from PIL import Image

import halftone

from conftest import assert_same_bytes, read

SIX = "spectra6-7in3-v2"  # six inks, 4-bit buffer
BWR = "hanshow-bwr"  # black, white, red: planes, raw, h

# (name, command-line flags, keyword arguments, extension, input)
CASES = [
    *[
        (f"intent-{i}", ["--device", SIX, "--intent", i], dict(device=SIX, intent=i), "png", "rgb")
        for i in ["perceptual", "relative", "saturation", "absolute"]
    ],
    (
        "steered",
        ["--device", SIX, "--exposure", "0.5", "--saturation", "1.3", "--tone", "0.6", "--gamut", "0.4"],
        dict(device=SIX, exposure=0.5, saturation=1.3, tone=0.6, gamut=0.4),
        "png",
        "rgb",
    ),
    (
        "steered-off",
        ["--device", BWR, "--exposure", "-1", "--saturation", "0", "--tone", "off", "--gamut", "off"],
        dict(device=BWR, exposure=-1, saturation=0, tone="off", gamut="off"),
        "png",
        "rgb",
    ),
    (
        "steered-auto-strings",
        ["--device", SIX, "--tone", "auto", "--gamut", "1"],
        dict(device=SIX, tone="auto", gamut="1"),
        "png",
        "rgba",
    ),
    (
        "steered-palette",
        ["--palette", "epaper-7", "--exposure", "0.25", "--saturation", "0.7"],
        dict(palette="epaper-7", exposure=0.25, saturation=0.7),
        "png",
        "rgb",
    ),
    ("device-grey-input", ["--device", SIX], dict(device=SIX), "png", "gray"),
    ("device-dbs", ["--device", SIX, "--method", "dbs", "--fit", "180x120"], dict(device=SIX, method="dbs", fit="180x120"), "png", "rgb"),
    ("device-dbs-bwr", ["--device", BWR, "--method", "dbs", "--passes", "8"], dict(device=BWR, method="dbs", passes=8), "png", "rgb"),
    ("device-ordered", ["--device", SIX, "--method", "ordered"], dict(device=SIX, method="ordered"), "png", "rgb"),
    (
        "device-ordered-mask",
        ["--device", BWR, "--method", "ordered", "--mask", "blue-noise-64", "--intent", "relative"],
        dict(device=BWR, method="ordered", mask="blue-noise-64", intent="relative"),
        "png",
        "rgb",
    ),
    ("palette-auto-8", ["--palette", "auto:8"], dict(palette="auto:8"), "png", "rgb"),
    ("palette-auto-8-ordered", ["--palette", "auto:8", "--method", "ordered"], dict(palette="auto:8", method="ordered"), "png", "rgb"),
    ("palette-auto-8-ppm", ["--palette", "auto:8", "--kernel", "stucki"], dict(palette="auto:8", kernel="stucki"), "ppm", "rgb"),
    # The panels' own buffers, for a three-ink and a six-ink panel.
    *[(f"bwr-{e}", ["--device", BWR], dict(device=BWR), e, "rgb") for e in ["raw", "bin", "h", "planes", "nibbles"]],
    ("bwr-nominal-png", ["--device", BWR, "--ink-colours", "nominal"], dict(device=BWR, ink_colours="nominal"), "png", "rgb"),
    *[(f"six-{e}", ["--device", SIX], dict(device=SIX), e, "rgb") for e in ["raw", "h", "nibbles"]],
    ("six-raw-dbs", ["--device", SIX, "--method", "dbs", "--width", "120"], dict(device=SIX, method="dbs", width=120), "raw", "rgb"),
    # Into the panel: padded with its white by default, or covering it, or inside it.
    *[(f"six-fit-{m}", ["--device", SIX, "--fit-mode", m], dict(device=SIX, fit_mode=m), "bin", "rgb") for m in ["pad", "cover", "inside"]],
    ("fit-pad-png", ["--fit", "100x100", "--fit-mode", "pad", "--levels", "3"], dict(fit="100x100", fit_mode="pad", levels=3), "png", "gray"),
    ("grey16-nibbles", ["--device", "grey16-6in", "--fit", "200x150"], dict(device="grey16-6in", fit="200x150"), "nibbles", "gray"),
]


@pytest.mark.parametrize("name,flags,kw,ext,src", CASES, ids=[c[0] for c in CASES])
def test_same_bytes_as_cli(cli, images, tmp_path, name, flags, kw, ext, src):
    assert_same_bytes(cli, images, tmp_path, name, flags, kw, ext, src)


def test_device_result(images):
    """A device result holds ink indices in the panel's order, the inks' measured colours
    as its palette, the panel's ppi, and is fitted into the panel with the aspect kept."""
    info = halftone.device(SIX)
    r = halftone.convert(images["rgb"], device=SIX)
    assert r.kind == "palette"
    assert r.palette == [ink["shown"] for ink in info["inks"]]
    assert r.dpi == info["ppi"]
    # 120x80 into 800x480: 720x480, centred on the panel's white (ink 1).
    assert (r.width, r.height) == (800, 480)
    white = [i for i, ink in enumerate(info["inks"]) if ink["name"] == "white"]
    assert white == [1]
    assert (r.array[:, :40] == 1).all() and (r.array[:, 760:] == 1).all()
    assert (r.array[:, 40:760] != 1).any()
    inside = halftone.convert(images["rgb"], device=SIX, fit_mode="inside")
    assert (inside.width, inside.height) == (720, 480)
    cover = halftone.convert(images["rgb"], device=SIX, fit_mode="cover")
    assert (cover.width, cover.height) == (800, 480)
    assert r.array.max() < len(info["inks"])
    # The nominal colours go to the file, not to the indices.
    n = halftone.convert(images["rgb"], device=SIX, ink_colours="nominal")
    assert np.array_equal(n.array, r.array)
    png = Image.open(io.BytesIO(n.encode("png")))
    flat = png.getpalette()[: 3 * len(info["inks"])]
    assert [tuple(flat[i : i + 3]) for i in range(0, len(flat), 3)] == [ink["nominal"] for ink in info["inks"]]


def test_planes_buffer_layout(images):
    """`planes` for a three-ink panel: a black plane then a red plane, a bit a pixel, rows
    padded to a byte (the sizes the panel's firmware reads)."""
    r = halftone.convert(images["rgb"], device=BWR)
    stride = (r.width + 7) // 8
    assert len(r.encode("planes")) == 2 * stride * r.height
    # raw: the 2-bit ink codes, four pixels a byte.
    assert len(r.encode("raw")) == (r.width * 2 + 7) // 8 * r.height
    header = r.encode("h").decode()
    assert f"#define HANSHOW_BWR_WIDTH {r.width}" in header
    assert f"#define HANSHOW_BWR_HEIGHT {r.height}" in header


def test_compare_device_same_figures(cli, images, tmp_path):
    """compare(..., device=) gives the figures of `halftone compare --device`, exactly, from
    the file, from the result in memory (with either ink colours: the measure reads the
    measured ones) and from the original's pixels."""
    for dev in [SIX, BWR]:
        cli("convert", images["rgb"], "-o", tmp_path / "h.png", "--device", dev, "--width", "120")
        want = json.loads(cli("compare", images["rgb"], tmp_path / "h.png", "--device", dev, "--json"))
        keys = ["de2000", "de76", "lightness_ratio", "pixels_per_degree", "device"]
        got = halftone.compare(images["rgb"], tmp_path / "h.png", device=dev)
        assert {k: got[k] for k in keys} == {k: want[k] for k in keys}
        r = halftone.convert(images["rgb"], device=dev, width=120)
        assert halftone.compare(images["rgb"], r, device=dev) == got
        n = halftone.convert(images["rgb"], device=dev, width=120, ink_colours="nominal")
        assert halftone.compare(images["rgb"], n, device=dev) == got
        pixels = np.asarray(Image.open(images["rgb"]))
        assert halftone.compare(pixels, r, device=dev) == got
    # The text output shows the same figures.
    text = cli("compare", images["rgb"], tmp_path / "h.png", "--device", BWR)
    de2000 = float(re.search(r"CIEDE2000\s+([0-9.]+)", text).group(1))
    assert de2000 == pytest.approx(got["de2000"], abs=5e-4)
    assert 0 < got["de2000"] < 100 and 0 < got["lightness_ratio"] < 2


def test_compare_device_profile_file(cli, images, tmp_path):
    """A profile file (`devices show NAME` written out) scores as the built-in it copies."""
    profile = tmp_path / "panel.toml"
    profile.write_text(cli("devices", "show", SIX))
    cli("convert", images["rgb"], "-o", tmp_path / "h.png", "--device", profile, "--width", "120")
    want = json.loads(cli("compare", images["rgb"], tmp_path / "h.png", "--device", profile, "--json"))
    got = halftone.compare(images["rgb"], tmp_path / "h.png", device=profile)
    assert got["de2000"] == want["de2000"] and got["de76"] == want["de76"]
    assert halftone.device(profile) == halftone.device(SIX)


def test_compare_device_errors(cli_error, images, tmp_path):
    cli_msg = cli_error("compare", images["rgb"], images["rgb"], "--device", "nope")
    with pytest.raises(ValueError) as e:
        halftone.compare(images["rgb"], images["rgb"], device="nope")
    assert str(e.value) == cli_msg


def test_devices_as_listed(cli):
    """devices() and device(name) hold what `halftone devices list` shows, in its order."""
    lines = cli("devices", "list").splitlines()
    names = [line.split()[0] for line in lines]
    assert list(halftone.devices()) == names
    for line in lines:
        m = re.fullmatch(r"(\S+)\s+(\d+)x(\d+)\s+(\d+) ppi\s+(\S+)\s+(.+)", line)
        assert m, line
        d = halftone.device(m.group(1))
        assert d["name"] == m.group(1)
        assert (d["width"], d["height"]) == (int(m.group(2)), int(m.group(3)))
        assert round(d["ppi"]) == int(m.group(4))
        assert d["colours"] == m.group(5)
        inks = [i["name"] for i in d["inks"]]
        assert m.group(6) == (f"{len(inks)} greys" if len(inks) > 7 else ",".join(inks))
        assert d["description"] == halftone.devices()[d["name"]]
        assert set(d["encodings"]) <= set(halftone.formats())
        assert d["bits"] in (1, 2, 4, 8)
        assert max(i["code"] for i in d["inks"]) < 2 ** d["bits"]


def flags_as_fields(msg):
    """A command-line message with its flags (`--exposure`) as the library names options
    (`` `exposure` ``), which is how Python reports them."""
    return re.sub(r"--([a-z][a-z-]*)", lambda m: "`" + m.group(1).replace("-", "_") + "`", msg)


@pytest.mark.parametrize(
    "flags,kw",
    [
        (["--exposure", "NaN"], dict(exposure=math.nan)),
        (["--exposure", "9"], dict(exposure=9)),
        (["--saturation", "4.5"], dict(saturation=4.5)),
    ],
    ids=["exposure-nan", "exposure-9", "saturation-4.5"],
)
def test_bad_numbers_cli_message(cli_error, images, tmp_path, flags, kw):
    cli_msg = cli_error("convert", images["rgb"], "-o", tmp_path / "x.png", "--device", SIX, *flags)
    # The command line: `invalid value '9' for '--exposure <STOPS>': expected ...` (a usage
    # error, from the option table's parser); Python: `exposure=9: expected ...`.
    flag, value = flags
    first = cli_msg.splitlines()[0]
    assert first.startswith(f"invalid value '{value}' for '{flag} <"), first
    cause = first.split("': ", 1)[1]
    assert cause.startswith("expected a number from "), first
    with pytest.raises(ValueError) as e:
        halftone.convert(images["rgb"], device=SIX, **kw)
    (key,) = kw
    assert str(e.value) == f"{key}={value}: {cause}"


def test_unknown_device_cli_message(cli_error, images, tmp_path):
    cli_msg = cli_error("convert", images["rgb"], "-o", tmp_path / "x.png", "--device", "spectra-6")
    assert "no built-in device of that name" in cli_msg
    with pytest.raises(ValueError) as e:
        halftone.convert(images["rgb"], device="spectra-6")
    assert str(e.value) == cli_msg
    with pytest.raises(ValueError) as e:
        halftone.device("spectra-6")
    assert str(e.value) == cli_msg


def test_bad_intent_names_the_cli_values(cli_error, images, tmp_path):
    cli_msg = cli_error("convert", images["rgb"], "-o", tmp_path / "x.png", "--device", SIX, "--intent", "foo")
    values = re.search(r"\[possible values: ([^\]]+)\]", cli_msg).group(1).split(", ")
    assert values == ["perceptual", "relative", "saturation", "absolute"]
    with pytest.raises(ValueError) as e:
        halftone.convert(images["rgb"], device=SIX, intent="foo")
    assert str(e.value) == "intent=foo: expected " + ", ".join(values[:-1]) + " or " + values[-1]


@pytest.mark.parametrize("key,value", [("tone", "2"), ("gamut", "x"), ("tone", "-0.5")])
def test_bad_amount_cli_message(cli_error, images, tmp_path, key, value):
    cli_msg = cli_error("convert", images["rgb"], "-o", tmp_path / "x.png", "--device", SIX, f"--{key}={value}")
    # clap: invalid value '2' for '--tone <auto|off|STRENGTH>': '2': expected auto, ...
    cause = cli_msg.split(f"'{value}': ", 1)[1].splitlines()[0]
    assert cause == "expected auto, off or a strength from 0 to 1"
    with pytest.raises(ValueError) as e:
        halftone.convert(images["rgb"], device=SIX, **{key: value})
    assert str(e.value) == f"{key}={value}: {cause}"


def test_planes_refused_for_six_inks(cli_error, images, tmp_path):
    cli_msg = cli_error("convert", images["rgb"], "-o", tmp_path / "x.planes", "--device", SIX)
    r = halftone.convert(images["rgb"], device=SIX)
    with pytest.raises(ValueError) as e:
        r.encode("planes")
    # The command line names its output file where Python names the bytes.
    assert cli_msg.split(": ", 1)[1] == str(e.value).split(": ", 1)[1]
    assert "planes are for two- and three-ink panels" in str(e.value)


def test_fit_mode_needs_a_box(cli_error, images, tmp_path):
    cli_msg = cli_error("convert", images["rgb"], "-o", tmp_path / "x.png", "--fit-mode", "pad")
    assert "--fit-mode pad needs a box" in cli_msg
    with pytest.raises(ValueError) as e:
        halftone.convert(images["rgb"], fit_mode="pad")
    assert str(e.value) == flags_as_fields(cli_msg)


def test_steering_needs_a_device_or_palette(cli_error, images, tmp_path):
    cli_msg = cli_error("convert", images["rgb"], "-o", tmp_path / "x.png", "--exposure", "1")
    with pytest.raises(ValueError) as e:
        halftone.convert(images["rgb"], exposure=1)
    assert str(e.value) == flags_as_fields(cli_msg)


def test_each_option_changes_the_picture(images):
    """Each intent and steering option reaches the rendering: none gives the default's
    indices (so the identity cases above compare different pictures)."""
    img = images["rgb"]
    base = halftone.convert(img, device=SIX, width=120).array
    for kw in [
        dict(intent="relative"),
        dict(intent="saturation"),
        dict(intent="absolute"),
        dict(exposure=0.5),
        dict(saturation=1.5),
        dict(tone="off"),
        dict(gamut="off"),
        dict(method="dbs"),
        dict(method="ordered"),
    ]:
        other = halftone.convert(img, device=SIX, width=120, **kw).array
        changed = np.mean(other != base)
        assert changed > 0.01, (kw, changed)



def test_compare_device_fits_the_original_as_convert_does(cli, images, tmp_path):
    """A panel-sized halftone against an original of another size: the original is fitted
    to the panel as `convert --device` fits it, in Python as on the command line (issue 45),
    with the same figures."""
    r = halftone.convert(images["rgb"], device=SIX)
    assert (r.width, r.height) == (800, 480)
    r.save(tmp_path / "big.png")
    want = json.loads(cli("compare", images["rgb"], tmp_path / "big.png", "--device", SIX, "--json"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = halftone.compare(images["rgb"], r, device=SIX)
        assert halftone.compare(images["rgb"], tmp_path / "big.png", device=SIX) == got
    assert got["de2000"] == want["de2000"] and got["de76"] == want["de76"]
    assert 0 < got["de2000"] < 40


def test_compare_device_warns_when_the_halftone_is_not_one(images, tmp_path):
    """A "halftone" with more colours than the panel has inks (the photo itself, panel-sized)
    is measured with a warning that names it, as the command line warns."""
    photo = Image.open(images["rgb"]).convert("RGB").resize((800, 480))
    fake = tmp_path / "fake.png"
    photo.save(fake)
    with pytest.warns(UserWarning, match=r"fake.png has 7 or more colours, more than the 6 inks"):
        got = halftone.compare(images["rgb"], fake, device=SIX)
    assert got["de2000"] > 0
