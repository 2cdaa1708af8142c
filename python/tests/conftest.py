"""Shared fixtures: the command-line binary and small test images from the repository."""

import os
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
IN_CI = bool(os.environ.get("CI"))


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
