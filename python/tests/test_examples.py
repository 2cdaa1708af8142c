"""The six examples of the README run as written, on a photo from the repository."""

import pathlib
import shutil
import subprocess

import pytest

from conftest import REPO, python_command

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"
PHOTO = REPO / "samples" / "raytrace.png"


def run(script, *args, cwd):
    p = subprocess.run([*python_command(), str(EXAMPLES / script), *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, f"{script} failed:\n{p.stdout}\n{p.stderr}"
    return p.stdout


def test_eink_panel(tmp_path):
    out = run("eink_panel.py", PHOTO, tmp_path / "panel.png", cwd=tmp_path)
    from PIL import Image

    im = Image.open(tmp_path / "panel.png")
    assert im.size[0] <= 800 and im.size[1] <= 480 and max(im.size[0] / 800, im.size[1] / 480) == pytest.approx(1, abs=0.01)
    assert "of 7" in out


def test_panel_buffer(tmp_path):
    out = run("panel_buffer.py", PHOTO, tmp_path / "frame", cwd=tmp_path)
    from PIL import Image

    im = Image.open(tmp_path / "frame.png")
    assert im.mode == "P" and im.size == (800, 480)
    # Two pixels a byte, rows padded to a byte.
    assert (tmp_path / "frame.bin").stat().st_size == (im.size[0] + 1) // 2 * im.size[1]
    de2000 = float(out.split(";")[1].split()[0])
    assert 0 < de2000 < 30, out  # 9.79 measured on raytrace.png


def test_receipt(tmp_path):
    run("receipt.py", PHOTO, tmp_path / "r.escpos", cwd=tmp_path)
    data = (tmp_path / "r.escpos").read_bytes()
    assert b"\x1dv0" in data and data.endswith(b"\x1dV\x42\x00") or b"\x1dV" in data


def test_cmyk_plates(tmp_path):
    out = run("cmyk_plates.py", PHOTO, tmp_path / "plates.tif", cwd=tmp_path)
    for ink in ["cyan", "magenta", "yellow", "black"]:
        assert (tmp_path / f"plates-{ink}.tif").stat().st_size > 0
        assert ink in out
    assert (tmp_path / "plates-preview.png").exists()


def test_compare(tmp_path):
    out = run("compare_methods.py", PHOTO, cwd=tmp_path)
    assert out.count("HVS-PSNR") == 5


def test_batch(tmp_path):
    src = tmp_path / "photos"
    src.mkdir()
    for name in ["raytrace.png", "shading.png", "polyhedra.png"]:
        shutil.copy(REPO / "samples" / name, src / name)
    out = run("batch_folder.py", src, tmp_path / "out", cwd=tmp_path)
    assert sorted(out.split()) == ["polyhedra.png", "raytrace.png", "shading.png"]
    assert len(list((tmp_path / "out").iterdir())) == 3
