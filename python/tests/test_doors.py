"""The Python door and the command line take the same options and list the same names:
both are read from the library's one option table (`halftone options --json`)."""

import json

import numpy as np
import pytest

import halftone


@pytest.fixture(scope="module")
def table(cli):
    return json.loads(cli("options", "--json"))


def test_lists_are_the_command_lines(table):
    want = table["lists"]
    assert halftone.lists() == want
    assert halftone.methods() == want["methods"]
    assert halftone.kernels() == want["kernels"]
    assert halftone.palettes() == want["palettes"]
    assert halftone.masks() == want["masks"]
    assert halftone.spots() == want["spots"]
    assert halftone.formats() == want["formats"]
    assert sorted(halftone.devices()) == sorted(want["devices"])
    assert halftone.presets() == dict(want["presets"])
    for k in ["ostromoukhov", "zhou-fang", "riemersma", "tded"]:
        assert k in halftone.kernels(), k


def _value(opt):
    """A value the option takes: its default, else its first listed value, else a number."""
    if opt["default"] is not None:
        v = opt["default"]
    elif opt["values"]:
        v = opt["values"][0]
    else:
        v = "1"
    if v in ("true", "false"):
        return v == "true"
    return v


def _reader(opt):
    """Options that choose a method or format the option needs."""
    u = opt["used_by"]
    if isinstance(u, dict) and "methods" in u:
        return dict(method=u["methods"][0])
    if isinstance(u, dict) and "formats" in u:
        return dict(format=u["formats"][0])
    return {}


def test_every_flag_is_a_keyword(table):
    """Each option of the command line is a keyword argument of convert(): it may be refused
    for its value (a file that is not there), never as an unknown keyword."""
    img = np.full((8, 8), 128, np.uint8)
    names = {o["name"] for o in table["options"]}
    assert set(table["accepts"]) == names | {"preset", "presets"}
    doc = halftone.convert.__doc__
    for opt in table["options"]:
        name = opt["name"]
        assert name in doc, f"convert()'s docstring does not name {name}"
        for n in [name, *opt["aliases"]]:
            v = _value(opt)
            if n != name and isinstance(v, bool):
                v = not v
            kw = {**_reader(opt), n: v}
            try:
                halftone.convert(img, **kw)
            except TypeError as e:
                assert "unexpected keyword" not in str(e), (n, e)
            except (ValueError, OSError):
                pass


def test_unknown_names_refused_as_the_command_line_does(table, cli_error):
    img = np.full((8, 8), 128, np.uint8)
    with pytest.raises(TypeError, match="unexpected keyword argument 'levles'"):
        halftone.convert(img, levles=3)
    assert "levles" in cli_error("convert", "x.png", "--levles", "3")
