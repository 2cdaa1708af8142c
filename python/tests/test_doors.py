"""The Python door and the command line take the same options and list the same names:
both are read from the library's one option table (`halftone options --json`)."""

import json
import pathlib
import re

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


def test_the_stub_types_every_option(table):
    """The installed type stub's convert() has a keyword for each option, typed as the table
    says: the fixed values as a Literal, booleans as bool, whole numbers as int, numbers as
    float; and Format lists the formats written. So a type checker accepts every keyword the
    command line has a flag for, and refuses a value no door takes."""
    import ast

    stub = pathlib.Path(halftone.__file__).with_name("__init__.pyi")
    assert stub.is_file(), f"the wheel carries no type stub ({stub})"
    tree = ast.parse(stub.read_text())
    convert = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "convert")
    params = {a.arg: ast.unparse(a.annotation) for a in convert.args.kwonlyargs}
    plain = {"bool": "Optional[bool]", "int": "Optional[int]", "number": "Optional[float]"}
    for o in table["options"]:
        name = o["name"]
        assert name in params, f"__init__.pyi's convert() lacks {name}"
        if o["choices"] == "fixed":
            values = ", ".join(repr(v) for v in o["values"])
            assert params[name] == f"Optional[Literal[{values}]]", (name, params[name])
        elif o["kind"] in plain:
            assert params[name] == plain[o["kind"]], (name, params[name])
    fmt = next(n for n in tree.body if isinstance(n, ast.Assign) and n.targets[0].id == "Format")
    formats = [e.value for e in fmt.value.slice.elts]
    written = next(o["values"] for o in table["options"] if o["name"] == "format")
    assert formats == written


def test_the_docstring_carries_each_options_help(table):
    """convert()'s docstring is made from the option table: each option with its help
    (the command line's flags written as keywords) and its fixed values."""
    doc = " ".join(halftone.convert.__doc__.split())
    for o in table["options"]:
        assert f" {o['name']}: " in doc, o["name"]
        if o["choices"] == "fixed":
            assert "Values: " + ", ".join(o["values"]) + "." in doc, o["name"]
    assert "--" not in doc.split("Options:")[1], "a command-line flag left in the options"


def test_unknown_names_refused_as_the_command_line_does(table, cli_error):
    img = np.full((8, 8), 128, np.uint8)
    with pytest.raises(TypeError, match="unexpected keyword argument 'levles'"):
        halftone.convert(img, levles=3)
    assert "levles" in cli_error("convert", "x.png", "--levles", "3")


def test_options_the_method_does_not_read_are_refused_as_the_command_line_does(cli_error, images, tmp_path):
    """An option that the chosen method or format does not read is refused by Python with
    the command line's own message, not accepted silently (issue 45)."""
    img = np.full((8, 8), 128, np.uint8)
    cases = [
        (dict(method="ordered", kernel="stucki"), ["--method", "ordered", "--kernel", "stucki"], "png"),
        (dict(method="diffuse", mask="bayer8"), ["--method", "diffuse", "--mask", "bayer8"], "png"),
        (dict(format="pbm", maxval=15), ["--maxval", "15"], "pbm"),
    ]
    for kw, flags, ext in cases:
        want = cli_error("convert", images["gray"], "-o", tmp_path / f"x.{ext}", *flags)
        with pytest.raises(ValueError) as e:
            halftone.convert(img, **kw)
        got = str(e.value)
        # The same message, each door naming options its own way (`--kernel`, `kernel`).
        flags_named = re.sub(r"--([a-z-]+)", lambda m: "`" + m.group(1).replace("-", "_") + "`", want)
        assert got in flags_named, (kw, got, want)
        assert "does not use it" in got, got


@pytest.mark.parametrize("name", ["levels", "width", "maxval", "seed", "max_pixels"])
def test_out_of_range_integers_say_the_range(name):
    """An integer out of its option's range is a ValueError that names the range (issue 45:
    it was `TypeError: levels: expected a number, not int`)."""
    img = np.full((8, 8), 128, np.uint8)
    extra = {"maxval": dict(format="pgm", levels=4)}.get(name, {})
    for v in [2**64, 10**30, 10**60, -(2**70)]:
        with pytest.raises(ValueError) as e:
            halftone.convert(img, **{**extra, name: v})
        msg = str(e.value)
        assert msg.startswith(f"{name}={v}: "), msg
        assert re.search(r"from -?\d+ to \d+", msg), msg
        assert "not int" not in msg, msg
