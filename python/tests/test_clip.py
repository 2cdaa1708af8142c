"""Clips a frame at a time: ``halftone.Clip`` gives the command line's bytes for the same
frames (a numbered series of PGM files through ``halftone convert``), a still clip gives the
same halftone every frame, stable diffusion leaves still areas alone, and a path or a bad
option is refused."""

import numpy as np
import pytest

import halftone


def frames(n=5, w=96, h=64):
    """A grey ramp with a bright patch moving right, 6 px a frame."""
    base = np.tile((np.arange(w) * 255 // (w - 1)).astype(np.uint8), (h, 1))
    out = []
    for i in range(n):
        f = base.copy()
        f[20:36, 10 + 6 * i : 30 + 6 * i] = 235
        out.append(f)
    return out


def pgm(a):
    return b"P5\n%d %d\n255\n" % (a.shape[1], a.shape[0]) + a.tobytes()


CASES = [
    ({"method": "diffuse"}, ["-m", "diffuse"]),
    ({"method": "diffuse", "temporal": "frame"}, ["-m", "diffuse", "--temporal", "frame"]),
    ({"method": "ordered", "mask": "blue-noise-64"}, ["-m", "ordered", "--mask", "blue-noise-64"]),
    ({"method": "diffuse", "levels": 4, "width": 48}, ["-m", "diffuse", "--levels", "4", "--width", "48"]),
]


@pytest.mark.parametrize("kw,flags", CASES)
def test_clip_same_bytes_as_cli(cli, tmp_path, kw, flags):
    src, out = tmp_path / "in", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    fs = frames()
    for i, f in enumerate(fs):
        (src / f"{i:04d}.pgm").write_bytes(pgm(f))
    cli("convert", src / "%04d.pgm", "-o", out / "%04d.pgm", *flags)
    written = sorted(p for p in out.iterdir() if p.suffix == ".pgm")
    assert len(written) == len(fs)
    clip = halftone.Clip(**kw)
    results = list(clip.map(fs))
    for i, (r, path) in enumerate(zip(results, written)):
        assert r.encode("pgm") == path.read_bytes(), f"frame {i} of {kw}"
    # Something moved, so the frames are not all one.
    assert any((a.array != b.array).any() for a, b in zip(results, results[1:]))


@pytest.mark.parametrize("kw,flags", CASES)
def test_still_clip_gives_the_same_frame(kw, flags):
    f = frames(1)[0]
    clip = halftone.Clip(**kw)
    first = clip.next(f).array.copy()
    for _ in range(3):
        assert (clip.next(f).array == first).all()


def test_stable_diffusion_keeps_still_areas():
    """Frame by frame, the moving patch reroutes the error and dots far below it move;
    stable diffusion leaves the rows well below the patch as they were."""
    fs = frames()
    def moved_below(**kw):
        rs = list(halftone.Clip(method="diffuse", **kw).map(fs))
        return sum(int((a.array[48:] != b.array[48:]).sum()) for a, b in zip(rs, rs[1:]))
    assert moved_below(temporal="frame") > 50
    assert moved_below() == 0


def test_bad_frames_are_refused():
    clip = halftone.Clip(method="diffuse")
    clip.next(np.zeros((10, 12), np.uint8))
    with pytest.raises(TypeError):
        clip.next("frame.png")
    with pytest.raises(ValueError):
        halftone.Clip(method="nonsense")
