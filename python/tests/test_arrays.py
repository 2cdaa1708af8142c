"""Arrays as inputs, held to the limits of files before anything is copied (issue 45), and a
randomised walk over dtypes, shapes, strides and keyword values that must never crash the
interpreter: every call gives a result or a Python exception."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import halftone
from conftest import python_command
from numpy.lib.stride_tricks import as_strided


def run_child(code: str) -> subprocess.CompletedProcess:
    """Runs `code` in a fresh interpreter: an abort there cannot take the test run down."""
    return subprocess.run(
        [*python_command(), "-c", textwrap.dedent(code)],
        capture_output=True,
        text=True,
        timeout=120,
    )


def peak_rss_mib(pid_status: str) -> int:
    for line in pid_status.splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) // 1024
    raise AssertionError("no VmHWM in /proc/self/status")


# numpy refuses an array whose size in bytes does not fit its index type (`intp`): on a
# 32-bit interpreter (armv7) a terapixel view cannot exist. There the views are 20000 x 20000
# (1.6 GB as float32, under 2 GiB) held to a limit given, and for `compare` (which takes no
# limit) 46000 x 46000 bytes, over the default limit of 1e9 pixels.
WORD64 = np.dtype(np.intp).itemsize == 8
BIG = 1_000_000 if WORD64 else 20_000
VBIG = 1_000_000 if WORD64 else 46_000
LIMIT = {} if WORD64 else {"max_pixels": 10**8}


def test_zero_stride_view_of_a_terapixel_is_a_value_error_not_an_abort():
    # It aborted the interpreter: "memory allocation of 1000000000000 bytes failed".
    p = run_child(
        f"""
        import numpy as np, halftone
        from numpy.lib.stride_tricks import as_strided
        v = as_strided(np.zeros(1, np.uint8), ({VBIG}, {VBIG}), (0, 0))
        for dtype in (np.uint8, np.uint16, np.float32, np.bool_):
            a = as_strided(np.zeros(1, dtype), ({BIG}, {BIG}), (0, 0))
            try:
                halftone.convert(a, method="threshold", **{LIMIT!r})
            except ValueError as e:
                print("ValueError:", e)
            for kw in ({LIMIT!r}, {{"max_pixels": 10_000}}):
                try:
                    halftone.convert_to_bytes(a, "pbm", **kw)
                except ValueError as e:
                    print("ValueError:", e)
        try:
            halftone.compare(v, v)
        except ValueError as e:
            print("ValueError:", e)
        print("alive")
        print(open("/proc/self/status").read())
        """
    )
    assert p.returncode == 0, p.stderr
    out = p.stdout
    assert out.count("ValueError:") == 13, out
    assert "alive" in out
    for line in out.splitlines():
        if line.startswith("ValueError:"):
            assert "pixels, over the limit of" in line and "max_pixels" in line, line
    assert "over the limit of 10000 " in out
    assert f"{BIG}x{BIG} = {BIG * BIG} pixels" in out
    # Nothing was copied: the interpreter, numpy and the module, no more.
    assert peak_rss_mib(out) < 200, peak_rss_mib(out)


def test_view_over_the_pixel_limit_is_refused_before_any_copy():
    # 40000 x 40000 = 1.6 Gpx over the default limit of 1e9: it was copied whole (1.6 GB)
    # before the limit was checked. A transposed view (not C-contiguous) takes the
    # gathering path; its base is small, made with zero strides on one axis.
    p = run_child(
        """
        import numpy as np, halftone
        from numpy.lib.stride_tricks import as_strided
        row = np.zeros(40000, np.uint8)
        v = as_strided(row, (40000, 40000), (0, 1))
        for a in (v, v.T, v[:, ::-1]):
            try:
                halftone.convert(a, method="threshold")
                print("converted")
            except ValueError as e:
                print("ValueError:", e)
        print(open("/proc/self/status").read())
        """
    )
    assert p.returncode == 0, p.stderr
    assert p.stdout.count("ValueError:") == 3, p.stdout
    assert "40000x40000 = 1600000000 pixels, over the limit of 1000000000" in p.stdout
    assert peak_rss_mib(p.stdout) < 200, peak_rss_mib(p.stdout)


def test_array_within_pixels_but_over_the_sample_budget_is_refused():
    # 6000 x 6000 RGBA uint16: 36 Mpx within a limit of 40 Mpx, but 288 MB of samples over
    # the 64 MiB floor / 40 MB of the budget.
    a = as_strided(np.zeros(1, np.uint16), (6000, 6000, 4), (0, 0, 0))
    with pytest.raises(ValueError, match="bytes of samples that `max_pixels` 40000000 sets"):
        halftone.convert(a, method="threshold", max_pixels=40_000_000)


def test_views_within_the_limit_give_the_bytes_of_a_copy():
    rng = np.random.default_rng(7)
    base = rng.integers(0, 256, (64, 96, 3), dtype=np.uint8)
    for view in (base[::2, ::3], base[:, ::-1], base.transpose(1, 0, 2), np.asfortranarray(base)):
        got = halftone.convert_to_bytes(view, "pbm", method="threshold")
        want = halftone.convert_to_bytes(np.ascontiguousarray(view), "pbm", method="threshold")
        assert got == want


# ---- the Python door fuzzed: random dtypes, shapes, strides and keyword values --------

DTYPES = [np.uint8, np.uint16, np.float32, np.float64, np.bool_, np.int32, np.int8, np.complex64, np.float16]
KEYWORDS = {
    # (dbs left out: its search on a megapixel would make the walk slow, not crash it.)
    "method": ["threshold", "diffuse", "ordered", "pattern", "nope", 3, None],
    "levels": [2, 3, 16, 255, 256, 65536, 0, 1, -1, 2**70, 2.5, "4", None],
    "width": [1, 7, 64, 0, -3, 10**12, "x", None],
    "max_pixels": [1, 100, 10**9, 0, -1, 2**64, "many", None],
    "seed": [0, 1, -1, 2**64, None],
    "color": ["gray", "rgb", "cmyk", "ink", None],
    "palette": ["auto:4", "auto:0", "#000000,#ffffff", "", None],
    "rotate": ["auto", "90", 45, None],
    "fit": ["16x16", "0x1", "1x99999999", None],
}


def random_array(rng: np.random.Generator):
    dtype = DTYPES[rng.integers(len(DTYPES))]
    ndim = int(rng.integers(1, 5))
    shape = tuple(int(rng.choice([0, 1, 2, 3, 4, 5, 17, 40])) for _ in range(ndim))
    if rng.random() < 0.1:
        # Huge shapes over zero strides: nothing behind them.
        # (2**31 does not fit a 32-bit interpreter's index type: 2**31 - 1 there.)
        top = min(2**31, np.iinfo(np.intp).max)
        shape = tuple(int(rng.choice([1, 3, 10**5, 10**6, top])) for _ in range(ndim))
        # numpy's own bound: a size in bytes that fits its index type.
        bound = min(2**62, np.iinfo(np.intp).max // 2)
        while int(np.prod([float(n) for n in shape])) * np.dtype(dtype).itemsize >= bound:
            shape = shape[:-1]
        return as_strided(np.zeros(1, dtype), shape, (0,) * len(shape))
    size = int(np.prod(shape)) if shape else 1
    flat = (rng.random(size) * 1.2 - 0.1)
    if np.dtype(dtype).kind in "ui":
        flat = rng.integers(0, 256, size)
    if rng.random() < 0.05 and np.dtype(dtype).kind == "f":
        flat[rng.integers(max(size, 1)) if size else 0 : 1] = np.nan
    a = np.asarray(flat).astype(dtype).reshape(shape)
    # Strided views: reversed, stepped, transposed, Fortran order.
    r = rng.random()
    if r < 0.2 and a.ndim >= 2:
        a = a[::-1, ::2]
    elif r < 0.4 and a.ndim >= 2:
        a = np.swapaxes(a, 0, 1)
    elif r < 0.5:
        a = np.asfortranarray(a)
    elif r < 0.6 and a.ndim >= 2 and a.shape[0] > 0:
        # Every row the first one: zero stride on the first axis (reads within the array).
        a = as_strided(a, a.shape, (0,) + a.strides[1:])
    return a


def test_python_door_never_crashes_on_random_arrays_and_keywords():
    """Each call either returns or raises an ordinary Python exception. It runs in a child
    interpreter: an abort (SIGABRT) or a segfault there shows as a failure here, with the
    seed and the case that did it."""
    seed = int(os.environ.get("HALFTONE_FUZZ_SEED", "45"))
    cases = int(os.environ.get("HALFTONE_FUZZ_CASES", "300"))
    p = run_child(
        f"""
        import sys, numpy as np, halftone
        sys.path.insert(0, {os.path.dirname(__file__)!r})
        from test_arrays import random_array, KEYWORDS
        rng = np.random.default_rng({seed})
        kinds = {{}}
        for i in range({cases}):
            a = random_array(rng)
            kw = {{}}
            for k, values in KEYWORDS.items():
                if rng.random() < 0.3:
                    v = values[rng.integers(len(values))]
                    if v is not None:
                        kw[k] = v
            kw.setdefault("max_pixels", 1_000_000)
            print("case", i, a.dtype, a.shape, a.strides, kw, flush=True)
            for call in ("convert", "bytes", "compare"):
                try:
                    if call == "convert":
                        halftone.convert(a, **kw)
                    elif call == "bytes":
                        halftone.convert_to_bytes(a, "pbm", **kw)
                    elif a.size < 10**5:
                        halftone.compare(a, a)
                    kinds["ok"] = kinds.get("ok", 0) + 1
                except (ValueError, TypeError, OverflowError, MemoryError) as e:
                    kinds[type(e).__name__] = kinds.get(type(e).__name__, 0) + 1
        print("done", kinds)
        """
    )
    tail = "\n".join(p.stdout.splitlines()[-3:])
    assert p.returncode == 0, f"exit {p.returncode}; last case:\n{tail}\n{p.stderr[-2000:]}"
    assert "done" in p.stdout, tail
    # The walk reached both ends: conversions that worked and refusals.
    assert "'ok'" in tail and "ValueError" in tail, tail
