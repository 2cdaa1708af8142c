"""Shared fixtures: the command-line binary and small test images from the repository."""

import os
import pathlib
import shlex
import shutil
import subprocess
import sys

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
IN_CI = bool(os.environ.get("CI"))


def python_command() -> list:
    """The command that starts this interpreter in a child process: `sys.executable`, after
    $HALFTONE_PYTHON_LAUNCHER when set (e.g. `qemu-aarch64 -L SYSROOT` to test an ARM wheel
    under qemu-user on a host that cannot exec ARM binaries itself)."""
    return shlex.split(os.environ.get("HALFTONE_PYTHON_LAUNCHER", "")) + [sys.executable]


def missing(what: str):
    """A missing tool fails in CI and skips, loudly, elsewhere."""
    if IN_CI:
        pytest.fail(f"{what} is missing (CI is set, so this is a failure)")
    print(f"\n*** SKIPPED: {what} is missing ***", file=sys.stderr)
    pytest.skip(what + " is missing")


@pytest.fixture(scope="session")
def cli():
    """The command line to compare bytes with: $HALFTONE_CLI, or target/release/halftone."""
    path = os.environ.get("HALFTONE_CLI") or str(REPO / "target" / "release" / "halftone")
    if not os.access(path, os.X_OK):
        missing(f"the halftone binary ({path}; build it with cargo build --release)")

    def run(*args):
        p = subprocess.run([path, *map(str, args)], capture_output=True, text=True)
        if p.returncode != 0:
            raise AssertionError(f"halftone {' '.join(map(str, args))} failed: {p.stderr}")
        return p.stdout

    return run


@pytest.fixture(scope="session")
def cli_error(cli):
    """The message of a command line that must fail: its stderr without the `halftone: `
    prefix (or clap's `error: `), on one line."""
    path = os.environ.get("HALFTONE_CLI") or str(REPO / "target" / "release" / "halftone")

    def run(*args):
        p = subprocess.run([path, *map(str, args)], capture_output=True, text=True)
        if p.returncode == 0:
            raise AssertionError(f"halftone {' '.join(map(str, args))} succeeded; it should fail")
        text = p.stderr.strip()
        for prefix in ("halftone: ", "error: "):
            if text.startswith(prefix):
                text = text[len(prefix):]
        return text

    return run


@pytest.fixture(scope="session")
def images(tmp_path_factory):
    """Small PNG inputs cut from the repository's samples: grey, RGB and RGBA."""
    from PIL import Image

    d = tmp_path_factory.mktemp("images")
    src = Image.open(REPO / "samples" / "raytrace.png").convert("RGB")
    rgb = src.crop((40, 30, 40 + 120, 30 + 80))
    out = {}
    out["rgb"] = d / "rgb.png"
    rgb.save(out["rgb"])
    out["gray"] = d / "gray.png"
    rgb.convert("L").save(out["gray"])
    rgba = rgb.copy()
    alpha = np.tile(np.linspace(0, 255, rgb.width).astype(np.uint8), (rgb.height, 1))
    rgba.putalpha(Image.fromarray(alpha))
    out["rgba"] = d / "rgba.png"
    rgba.save(out["rgba"])
    return out


def read(path):
    return pathlib.Path(path).read_bytes()


def assert_same_bytes(cli, images, tmp_path, name, flags, kw, ext, src):
    """`halftone convert SRC -o cli.EXT FLAGS` and the Python calls with `kw` give the same
    bytes: from the path (encode, save, the streaming convert_to_bytes), from the file's
    bytes, from the decoded pixels as a numpy array and as a Pillow image."""
    import halftone
    from PIL import Image

    out = tmp_path / f"cli.{ext}"
    cli("convert", images[src], "-o", out, *flags)
    want = read(out)
    r = halftone.convert(images[src], **kw)
    assert r.encode(ext) == want, f"{name}: encode differs from the command line"
    saved = tmp_path / f"py.{ext}"
    r.save(saved)
    assert read(saved) == want, f"{name}: save differs"
    assert halftone.convert(read(images[src]), **kw).encode(ext) == want, f"{name}: from bytes differs"
    assert halftone.convert_to_bytes(images[src], ext, **kw) == want, f"{name}: convert_to_bytes differs"
    pixels = np.asarray(Image.open(images[src]))
    assert halftone.convert(pixels, **kw).encode(ext) == want, f"{name}: from numpy differs"
    assert halftone.convert(Image.open(images[src]), **kw).encode(ext) == want, f"{name}: from Pillow differs"
    return r, want
