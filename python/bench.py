"""halftone against Pillow, epaper-dithering and dither-go, in one process.

Jobs (the pixels already decoded in memory for every library; best of --runs calls made back
to back after a warm-up, the same for every library: see best()):
  bilevel  grey → black and white, Floyd–Steinberg: halftone (linear light), Pillow
           convert('1') (gamma space), dither-go (FloydSteinberg to black and white);
  palette  RGB → a 6-colour e-paper palette (the Spectra 6 colours epaper-dithering ships),
           Floyd–Steinberg: halftone (palette file of the same colours), Pillow quantize
           (fixed palette, FLOYDSTEINBERG), epaper-dithering dither_image (its defaults but
           mode FLOYD_STEINBERG), dither-go;
  device   RGB → the Spectra 6 panel's measured inks (device spectra6-7in3-v2, perceptual
           intent: tone and gamut fitted to the inks): halftone convert(device=...) against
           epaper-dithering dither_image(SPECTRA_7_3_6COLOR_V2): Floyd–Steinberg (its
           defaults but mode FLOYD_STEINBERG: plain diffusion), and DBS (halftone
           method="dbs" against its tone="auto", gamut="auto", dbs=True). halftone is given
           width= the picture's own, which keeps its size (without it a device fits the
           picture into its 800x480); at 800x480 that is the same call. DBS runs on the
           24 MP photo only with --dbs-24mp (minutes a run for each library).
on an 800x480 panel image and a 24 MP photo (a real photo from scikit-image, or
matplotlib's grace_hopper.jpg, upscaled); then halftone calls from two threads at once
against one after the other, each call on one thread (threads=1: a single call otherwise uses
every core).

    python bench.py [--runs 3] [--no-24mp] [--dbs-24mp] [--json out.json]

Peers that do not import are reported as missing and left out.
"""

from __future__ import annotations

import argparse
import json
import os

# Idle OpenBLAS threads (numpy and scipy, loaded for the sample photo) spin for a while after
# each call and take cores from whatever runs next: one BLAS thread, so that every library
# timed here gets the machine's cores.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import pathlib
import resource
import shutil
import subprocess
import tempfile
import threading
import time

import sys

import numpy as np
from PIL import Image

# This script sits next to the package's source folder: import the installed package.
sys.path[:] = [p for p in sys.path if pathlib.Path(p or ".").resolve() != pathlib.Path(__file__).resolve().parent]
import halftone  # noqa: E402


def photo() -> Image.Image:
    """A real photograph from an installed package."""
    try:
        from skimage import data

        return Image.fromarray(data.astronaut()).convert("RGB")
    except Exception:
        pass
    try:
        import matplotlib.cbook as cbook

        with cbook.get_sample_data("grace_hopper.jpg") as f:
            return Image.open(f).convert("RGB")
    except Exception:
        pass
    raise SystemExit("bench.py needs scikit-image or matplotlib for a sample photo")


# epaper-dithering's SPECTRA_7_3_6COLOR (6.1.1), for when it is not installed.
SPECTRA6 = [(26, 13, 35), (185, 202, 205), (202, 184, 0), (121, 9, 0), (0, 69, 139), (40, 82, 57)]


def cli_binary() -> str | None:
    """The `halftone` binary: $HALFTONE_BIN, the repository's release build, or PATH's."""
    repo = pathlib.Path(__file__).resolve().parent.parent / "target" / "release" / "halftone"
    for c in [os.environ.get("HALFTONE_BIN"), str(repo) if repo.exists() else None, shutil.which("halftone")]:
        if c:
            return c
    print("halftone CLI: not found (set HALFTONE_BIN); its row is left out")
    return None


def best(fn, runs: int) -> float:
    """The shortest of `runs` timed calls, after a pause and a warm-up.

    The pause lets worker threads that the library timed before left spinning (rayon's,
    OpenBLAS's) go to sleep, so that they do not take this one's cores. The warm-up repeats
    the call, untimed, for a tenth of a second (at least once): it brings the library's code
    and tables into the caches and its worker threads and the machine's cores up to speed,
    as hyperfine's --warmup and timeit's repeats do; then the calls run back to back, as a
    batch of pictures would. (On the 2-core virtual machine of these figures a core left
    idle for 0.2 s takes some 30 ms of work to come back: without the warm-up, a call that
    uses both cores ran at one core's speed.) A first call of half a second or more needs no
    warming: it counts.
    """
    time.sleep(0.2)
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    times = [first] if first >= 0.5 else []
    while not times and time.perf_counter() - t0 < 0.1:
        fn()
    while len(times) < runs:
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def peers():
    found = {}
    try:
        import epaper_dithering

        found["epaper-dithering"] = epaper_dithering
    except Exception as e:  # noqa: BLE001
        print(f"epaper-dithering: not available ({e})")
    try:
        import dither_go

        found["dither-go"] = dither_go
    except Exception as e:  # noqa: BLE001
        print(f"dither-go: not available ({e})")
    return found


def threads_only(label: str, runs: int) -> None:
    """The two-threads rows for one size, as JSON on stdout (run in a child process)."""
    w, h = {"800x480": (800, 480), "24MP": (6000, 4000)}[label]
    rgb_img = photo().resize((w, h), Image.Resampling.BICUBIC)
    rgb = np.asarray(rgb_img)
    grey = np.asarray(rgb_img.convert("L"))
    tmp = pathlib.Path(tempfile.mkdtemp())
    pal_file = tmp / "spectra6.txt"
    pal_file.write_text("".join(f"#{r:02x}{g:02x}{b:02x}\n" for r, g, b in SPECTRA6))

    def two_threads(job):
        ts = [threading.Thread(target=job) for _ in range(2)]
        for t in ts:
            t.start()
        for t in ts:
            t.join()

    rows = []
    for job_name, job in [
        ("bilevel FS", lambda: halftone.convert(grey, threads=1)),
        ("palette-6 FS", lambda: halftone.convert(rgb, palette=str(pal_file), threads=1)),
    ]:
        one = best(lambda: (job(), job()), runs)
        two = best(lambda: two_threads(job), runs)
        rows.append(dict(size=label, job=f"{job_name} x2 one thread", lib="halftone", seconds=one))
        rows.append(dict(size=label, job=f"{job_name} x2 two threads", lib="halftone", seconds=two))
    print(json.dumps(rows))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--no-24mp", action="store_true")
    ap.add_argument("--dbs-24mp", action="store_true", help="also time device DBS on the 24 MP photo (slow)")
    ap.add_argument("--json")
    ap.add_argument("--threads-only", metavar="SIZE", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.threads_only:
        threads_only(a.threads_only, a.runs)
        return

    p = peers()
    src = photo()
    sizes = {"800x480": (800, 480)}
    if not a.no_24mp:
        sizes["24MP"] = (6000, 4000)
    tmp = pathlib.Path(tempfile.mkdtemp())
    spectra = None
    if "epaper-dithering" in p:
        spectra = p["epaper-dithering"].SPECTRA_7_3_6COLOR
        colours = list(spectra.colors.values())
    else:
        colours = SPECTRA6
    pal_file = tmp / "spectra6.txt"
    pal_file.write_text("".join(f"#{r:02x}{g:02x}{b:02x}\n" for r, g, b in colours))
    pal_img = Image.new("P", (1, 1))
    pal_img.putpalette([c for rgb in colours for c in rgb] + [0] * (3 * (256 - len(colours))))

    results = []
    notes = []
    dbs_seconds = {}
    load = os.getloadavg()
    print(f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} on {os.cpu_count()} CPUs (a shared machine shows in these figures)")
    for label, (w, h) in sizes.items():
        rgb_img = src.resize((w, h), Image.Resampling.BICUBIC)
        grey_img = rgb_img.convert("L")
        rgb = np.asarray(rgb_img)
        grey = np.asarray(grey_img)
        runs = a.runs
        row = lambda job, lib, t: results.append(dict(size=label, job=job, lib=lib, seconds=t))  # noqa: E731

        # bilevel
        row("bilevel FS", "halftone", best(lambda: halftone.convert(grey), runs))
        row("bilevel FS", "Pillow convert('1')", best(lambda: grey_img.convert("1"), runs))
        if "dither-go" in p:
            dg = p["dither-go"]
            path = tmp / f"grey-{label}.png"
            grey_img.save(path)
            d = dg.new_ditherer(dg.create_palette(["#000000", "#ffffff"]))
            d.Matrix = dg.ErrorDiffusers.FloydSteinberg
            go_img = dg.open_image(str(path))
            row("bilevel FS", "dither-go", best(lambda: d.DitherPaletted(go_img), runs))

        # 6-colour palette
        row("palette-6 FS", "halftone", best(lambda: halftone.convert(rgb, palette=str(pal_file)), runs))
        row(
            "palette-6 FS",
            "Pillow quantize",
            best(lambda: rgb_img.quantize(palette=pal_img, dither=Image.Dither.FLOYDSTEINBERG), runs),
        )
        if "epaper-dithering" in p:
            ed = p["epaper-dithering"]
            row(
                "palette-6 FS",
                "epaper-dithering",
                best(lambda: ed.dither_image(rgb_img, spectra, mode=ed.DitherMode.FLOYD_STEINBERG), runs),
            )
        if "dither-go" in p:
            dg = p["dither-go"]
            path = tmp / f"rgb-{label}.png"
            rgb_img.save(path)
            d6 = dg.new_ditherer(dg.create_palette(["#%02x%02x%02x" % c for c in colours]))
            d6.Matrix = dg.ErrorDiffusers.FloydSteinberg
            go_img = dg.open_image(str(path))
            row("palette-6 FS", "dither-go", best(lambda: d6.DitherPaletted(go_img), runs))

        # A panel's measured inks, the picture fitted to them (tone, gamut): Floyd–Steinberg,
        # then DBS. width= keeps the picture's size (a device alone fits it into 800x480).
        dev = "spectra6-7in3-v2"
        ed_scheme = p["epaper-dithering"].SPECTRA_7_3_6COLOR_V2 if "epaper-dithering" in p else None
        row("device-6 FS", "halftone", best(lambda: halftone.convert(rgb, device=dev, width=w), runs))
        if ed_scheme is not None:
            ed = p["epaper-dithering"]
            row(
                "device-6 FS",
                "epaper-dithering",
                best(lambda: ed.dither_image(rgb_img, ed_scheme, mode=ed.DitherMode.FLOYD_STEINBERG), runs),
            )
        if label == "24MP" and not a.dbs_24mp:
            small = dbs_seconds.get("800x480")
            guess = f"; about {small * w * h / (800 * 480):.0f} s a run for halftone from its 800x480 time" if small else ""
            notes.append(f"{label}: device DBS left out (too long for a routine run{guess}); --dbs-24mp times it")
        else:
            t = best(lambda: halftone.convert(rgb, device=dev, width=w, method="dbs"), runs)
            dbs_seconds[label] = t
            row("device-6 DBS", "halftone", t)
            if ed_scheme is not None:
                ed = p["epaper-dithering"]
                row(
                    "device-6 DBS",
                    "epaper-dithering",
                    best(lambda: ed.dither_image(rgb_img, ed_scheme, tone="auto", gamut="auto", dbs=True), runs),
                )

        # The command line on the same pixels and options: the whole process, a PPM file in
        # (read in a few milliseconds) and the palette image written as PPM to /dev/null.
        cli = cli_binary()
        if cli:
            ppm = tmp / f"rgb-{label}.ppm"
            rgb_img.save(ppm)
            cmd = [cli, "convert", str(ppm), "--palette", str(pal_file), "--format", "ppm", "-o", "/dev/null"]
            row("palette-6 FS", "halftone CLI (process)", best(lambda: subprocess.run(cmd, check=True), runs))
            cmd = [cli, "convert", str(ppm), "--device", dev, "--width", str(w), "--format", "ppm", "-o", "/dev/null"]
            row("device-6 FS", "halftone CLI (process)", best(lambda: subprocess.run(cmd, check=True), runs))

        # threads: the same job twice, one call after the other and two calls at once, each
        # call on one thread (threads=1: a single call otherwise spreads over every core), so
        # this shows that calls from two threads do not wait for each other (no lock, the GIL
        # released), as in a server or a pool. In a child process, for a fresh heap.
        child = subprocess.run(
            [sys.executable, __file__, "--threads-only", label, "--runs", str(runs)],
            capture_output=True,
            text=True,
            check=True,
        )
        results.extend(json.loads(child.stdout))

    width = max(len(r["job"]) for r in results) + 2
    print(f"{'size':8} {'job':{width}} {'library':22} {'seconds':>9} {'vs halftone':>12}")
    ref = {(r["size"], r["job"]): r["seconds"] for r in results if r["lib"] == "halftone"}
    for r in results:
        x = r["seconds"] / ref[(r["size"], r["job"])]
        print(f"{r['size']:8} {r['job']:{width}} {r['lib']:22} {r['seconds']:9.3f} {x:11.2f}x")
    for label in sizes:
        for job in ["bilevel FS", "palette-6 FS"]:
            one = ref.get((label, f"{job} x2 one thread"))
            two = ref.get((label, f"{job} x2 two threads"))
            if one and two:
                print(f"{label:8} {job}: two threads {one / two:.2f}x one thread")
    for n in notes:
        print(n)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process (all libraries together): {peak:.0f} MB")
    if a.json:
        pathlib.Path(a.json).write_text(json.dumps(dict(load=load, results=results, notes=notes), indent=1))


if __name__ == "__main__":
    main()
