#!/usr/bin/env python3
"""halftone against epaper-dithering on real photographs, panel by panel, in one run.

For every photo and every panel both projects have measured inks for, the photo is fitted
to the panel once (Pillow, Lanczos) and that same picture is given to:

  halftone:          `convert --device D` (Floyd-Steinberg, perceptual intent, the default),
                     `convert --device D --method dbs` (palette DBS), and
                     `convert --device D --intent absolute` (the inks as measured, no mapping);
  epaper-dithering:  `dither_image(img, PALETTE, mode=FLOYD_STEINBERG)` (plain diffusion, its
                     defaults otherwise) and with `tone='auto', gamut='auto', dbs=True` (its best).

Every result is scored by `halftone compare --device D`: the displayed pixels are the
panel's measured ink colours, seen by a viewer adapted to the panel's white and black
(Bradford, black-point compensation), S-CIELAB at the panel's pixels a degree, mean
CIEDE2000 (README, "The measure"). Times: epaper-dithering inside the call (Floyd-Steinberg:
the best of three calls after a warm-up; its DBS: one call); halftone for the whole
process (decode, map, dither, PNG encode, the best of three runs) and, when the Python package
imports, inside the call too, timed the same way as epaper-dithering's.

Photos: the real photographs of OpenCV's sample data (Debian package opencv-doc): a
package, and none of them used to tune anything here. The script downloads the package
with `apt-get download` when --photos is not given.

    python3 -m venv /tmp/v && /tmp/v/bin/pip install epaper-dithering==6.1.1 Pillow ./python
    /tmp/v/bin/python scripts/epaper-compare.py --halftone target/release/halftone

Prints one table per panel and a summary; --json FILE writes every figure.

A corpus of one's own: --photos DIR --all takes every PNG and JPEG in DIR (issue 46 used 48
photographs from five Debian packages: opencv-doc, python3-skimage, mate-backgrounds,
lomiri-wallpapers-16.04 and -20.04; docs/devices.md gives the list). --runs 1 times each
command once; --ed-from JSON takes epaper-dithering's results from an earlier run's --json
(they do not change with halftone), so a before/after pair costs halftone's runs alone.
Beside CIEDE2000, each result gets a hue error: the displayed and the original picture
blurred alike (a Gaussian of 4 pixels, in the adapted viewer's linear light), then the mean
CIELCh hue-angle difference in degrees, weighted by the original's chroma (pixels of chroma
above 10 only). The worst photos (our DBS against epaper-dithering's best) end the report.
"""

import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile
import time

import epaper_dithering as ed
from PIL import Image

try:  # The Python package, for times inside the call like epaper-dithering's.
    import numpy as np
    import halftone as ht_py
except ImportError:
    ht_py = None

PHOTOS = [
    "baboon.jpg", "fruits.jpg", "building.jpg", "home.jpg", "messi5.jpg",
    "leuvenA.jpg", "butterfly.jpg", "squirrel_cls.jpg", "aloeL.jpg", "orange.jpg",
]

# Our device → epaper-dithering's palette of the same panel.
PANELS = {
    "spectra6-7in3-v2": "SPECTRA_7_3_6COLOR_V2",
    "spectra6-7in3": "SPECTRA_7_3_6COLOR",
    "bwry-3in97": "BWRY_3_97",
    "bwry-4in2": "BWRY_4_2",
    "mono-4in26": "MONO_4_26",
    "solum-bwr": "SOLUM_BWR",
    "hanshow-bwr": "HANSHOW_BWR",
    "hanshow-bwy": "HANSHOW_BWY",
}


def hue_error(original, displayed, colours, blur=4.0):
    """Mean CIELCh hue-angle difference (degrees) between `original` and `displayed` (PNG
    paths; the displayed one in the panel's measured colours `colours`), each blurred by a
    Gaussian of `blur` pixels in linear light as the viewer adapted to the panel's white and
    black sees it (per channel), weighted by the original's chroma where that is over 10."""
    import numpy as np

    def lin(a):
        a = a / 255.0
        return np.where(a <= 0.04045, a / 12.92, ((a + 0.055) / 1.055) ** 2.4)

    shown = lin(np.array(colours, dtype=float))
    y = shown @ np.array([0.2126, 0.7152, 0.0722])
    white, black = shown[y.argmax()], shown[y.argmin()]
    o = lin(np.asarray(Image.open(original).convert("RGB"), dtype=float))
    d = lin(np.asarray(Image.open(displayed).convert("RGB"), dtype=float))
    d = np.clip((d - black) / np.maximum(white - black, 1e-6), 0, None)
    r = int(3 * blur)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / blur) ** 2)
    k /= k.sum()

    def smooth(a):
        pad = np.pad(a, ((r, r), (r, r), (0, 0)), mode="reflect")
        a = sum(k[i] * pad[i:i + a.shape[0], r:r + a.shape[1]] for i in range(2 * r + 1))
        return a

    def lab(a):
        m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                      [0.0193, 0.1192, 0.9505]])
        xyz = a @ m.T / np.array([0.9505, 1.0, 1.089])
        f = np.where(xyz > 0.008856, np.cbrt(xyz), 7.787 * xyz + 16 / 116)
        return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]),
                         200 * (f[..., 1] - f[..., 2])], -1)

    lo, ld = lab(smooth(o)), lab(smooth(d))
    co = np.hypot(lo[..., 1], lo[..., 2])
    dh = np.degrees(np.abs(np.angle(np.exp(1j * (np.arctan2(lo[..., 2], lo[..., 1])
                                                   - np.arctan2(ld[..., 2], ld[..., 1]))))))
    wgt = np.where(co > 10, co, 0)
    return float((wgt * dh).sum() / wgt.sum()) if wgt.sum() > 0 else 0.0


def fetch_photos(where):
    os.makedirs(where, exist_ok=True)
    subprocess.run(["apt-get", "download", "-qq", "opencv-doc"], cwd=where, check=True)
    deb = sorted(glob.glob(os.path.join(where, "opencv-doc_*.deb")))[-1]
    subprocess.run(["dpkg-deb", "-x", deb, os.path.join(where, "x")], check=True)
    return os.path.join(where, "x/usr/share/doc/opencv-doc/examples/data")


def device_info(halftone, name):
    """Panel size, rotation, ink names and measured colours from `devices show`."""
    import tomllib

    text = subprocess.run([halftone, "devices", "show", name], capture_output=True,
                          text=True, check=True).stdout
    d = tomllib.loads(text)
    return d


def fit(img, w, h):
    s = min(w / img.width, h / img.height)
    size = (max(1, round(img.width * s)), max(1, round(img.height * s)))
    return img.resize(size, Image.LANCZOS)


def shown(ink):
    m = ink.get("measured", ink["nominal"])
    return tuple(int(m.lstrip("#")[i:i + 2], 16) for i in (0, 2, 4))


def score(halftone, device, original, displayed, neutral=None):
    """`compare --device` figures; with `neutral` (a profile file from `neutral_profile`) the
    CIEDE2000 under the neutral black-point compensation is added as `de2000_neutral`."""
    out = subprocess.run([halftone, "compare", original, displayed, "--device", device,
                          "--json"], capture_output=True, text=True, check=True).stdout
    res = json.loads(out)
    if neutral:
        out = subprocess.run([halftone, "compare", original, displayed, "--device", neutral,
                              "--json"], capture_output=True, text=True, check=True).stdout
        res["de2000_neutral"] = json.loads(out)["de2000"]
    return res


def neutral_profile(halftone, device, where):
    """A profile file for `device` whose black ink is the neutral of its luminance (the
    white ink scaled by the black's luminance over the white's), for `compare --device`.

    `compare` takes the darkest and lightest inks of the profile as the panel's black and
    white and the displayed pixels as they are; its compensation, per channel
    `X' = (X - X_b) X_w / (X_w - X_b)`, is with a neutral black `XYZ' = (XYZ - Y_b W) /
    (1 - Y_b)`: the panel's black keeps its tint instead of being taken to black. (The
    neutral is written in 8-bit sRGB, as profiles hold inks.)"""
    text = subprocess.run([halftone, "devices", "show", device], capture_output=True,
                          text=True, check=True).stdout
    import tomllib

    d = tomllib.loads(text)

    def lin(v):
        v = v / 255.0
        return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4

    def enc(v):
        v = min(max(v, 0.0), 1.0)
        v = 12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
        return round(255 * v)

    def rgb(ink):
        return [lin(c) for c in shown(ink)]

    lum = lambda c: 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]  # noqa: E731
    inks = d["ink"]
    white = max(inks, key=lambda k: lum(rgb(k)))
    black = min(inks, key=lambda k: lum(rgb(k)))
    s = lum(rgb(black)) / lum(rgb(white))
    grey = "#" + "".join(f"{enc(s * c):02x}" for c in rgb(white))
    key = 'measured = "' + black.get("measured", "") + '"'
    at = text.index('name = "' + black["name"] + '"')
    end = text.index(key, at) if "measured" in black else None
    if end is None:
        raise SystemExit(f"{device}: the black ink has no measured colour")
    text = text[:end] + f'measured = "{grey}"' + text[end + len(key):]
    text = text.replace(f'name = "{d["name"]}"', f'name = "{d["name"]}-neutral-black"', 1)
    path = os.path.join(where, f"{device}-neutral-black.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def timed_process(cmd, runs=3):
    best = float("inf")
    for _ in range(runs):
        t = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        best = min(best, time.perf_counter() - t)
    return best


def best_call(fn, runs=3):
    """The shortest of `runs` calls made back to back after a pause and a warm-up (the same
    for both libraries: the pause lets the other library's worker threads sleep; the
    warm-up, the call repeated untimed for a tenth of a second, brings this one's threads
    and the machine's cores up to speed), and the first call's result."""
    time.sleep(0.2)
    t0 = time.perf_counter()
    out = fn()
    while time.perf_counter() - t0 < 0.1:
        fn()
    best = float("inf")
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--halftone", default="target/release/halftone")
    ap.add_argument("--photos", help="folder holding the photos (default: download opencv-doc)")
    ap.add_argument("--panels", default=",".join(PANELS))
    ap.add_argument("--limit", type=int, help="use the first N photos")
    ap.add_argument("--json", help="write every figure here")
    ap.add_argument("--keep", help="keep the images in this folder")
    ap.add_argument("--all", action="store_true", help="every PNG and JPEG in --photos")
    ap.add_argument("--runs", type=int, default=3, help="timed runs of each command")
    ap.add_argument("--ed-from", help="epaper-dithering's results from an earlier --json")
    ap.add_argument("--worst", type=int, default=5, help="worst photos listed per panel")
    ap.add_argument("--no-ed-fs", action="store_true",
                    help="leave out epaper-dithering's plain diffusion (saves a third of the time)")
    ap.add_argument("--neutral-black", action="store_true",
                    help="score our DBS and epaper-dithering's best also under the neutral "
                         "black-point compensation (XYZ' = (XYZ - Y_b W) / (1 - Y_b))")
    a = ap.parse_args()
    earlier = {}
    if a.ed_from:
        with open(a.ed_from) as f:
            earlier = {(r["device"], r["photo"]): r for r in json.load(f)}
    work = a.keep or tempfile.mkdtemp(prefix="epaper-compare-")
    os.makedirs(work, exist_ok=True)
    photos = a.photos or fetch_photos(os.path.join(work, "photos"))
    photo_list = PHOTOS[: a.limit or len(PHOTOS)]
    if a.all:
        photo_list = sorted(f for f in os.listdir(photos)
                            if f.lower().endswith((".png", ".jpg", ".jpeg")))[: a.limit]
    rows = []
    for device in a.panels.split(","):
        info = device_info(a.halftone, device)
        palette = getattr(ed, PANELS[device])
        names = list(palette.colors.keys())
        ours = [ink["name"] for ink in info["ink"]]
        colours = [shown(ink) for ink in info["ink"]]
        # Their index → our ink (by name), so both are shown in the same measured colours.
        to_ours = [ours.index(n) for n in names]
        w, h = info["width"], info["height"]
        neutral = neutral_profile(a.halftone, device, work) if a.neutral_black else None
        if info.get("rotation", 0) in (90, 270):
            w, h = h, w
        for photo in photo_list:
            stem = f"{device}-{os.path.splitext(photo)[0]}"
            img = fit(Image.open(os.path.join(photos, photo)).convert("RGB"), w, h)
            orig = os.path.join(work, stem + "-photo.png")
            img.save(orig)
            res = {"device": device, "photo": photo, "size": img.size}
            for label, extra in [("ht_fs", []), ("ht_dbs", ["--method", "dbs"]),
                                 ("ht_abs", ["--intent", "absolute"])]:
                out = os.path.join(work, f"{stem}-{label}.png")
                cmd = [a.halftone, "convert", orig, "-o", out, "--device", device,
                       "--width", str(img.width)] + extra
                res[label + "_s"] = timed_process(cmd, a.runs if label != "ht_dbs" else 1)
                res[label] = score(a.halftone, device, orig, out,
                                   neutral if label == "ht_dbs" else None)
                res[label]["hue"] = hue_error(orig, out, colours)
            if ht_py is not None and a.runs > 1:
                # The same calls inside Python (same library, same picture), timed as
                # epaper-dithering's are.
                arr = np.asarray(img)
                res["ht_fs_call_s"], _ = best_call(
                    lambda: ht_py.convert(arr, device=device, width=img.width))
                t = time.perf_counter()
                ht_py.convert(arr, device=device, width=img.width, method="dbs")
                res["ht_dbs_call_s"] = time.perf_counter() - t
            for label, kw in [("ed_fs", {}), ("ed_best", {"tone": "auto", "gamut": "auto",
                                                          "dbs": True})]:
                if label == "ed_fs" and a.no_ed_fs:
                    continue
                before = earlier.get((device, photo), {})
                if label in before and (not neutral or label != "ed_best"
                                        or "de2000_neutral" in before[label]):
                    res[label] = before[label]
                    res[label + "_s"] = before[label + "_s"]
                    continue
                call = lambda: ed.dither_image(img, palette,  # noqa: E731
                                               mode=ed.DitherMode.FLOYD_STEINBERG, **kw)
                if label == "ed_fs":
                    res[label + "_s"], p = best_call(call)
                else:
                    t = time.perf_counter()
                    p = call()
                    res[label + "_s"] = time.perf_counter() - t
                disp = Image.new("RGB", img.size)
                disp.putdata([colours[to_ours[i]] for i in p.getdata()])
                out = os.path.join(work, f"{stem}-{label}.png")
                disp.save(out)
                res[label] = score(a.halftone, device, orig, out,
                                   neutral if label == "ed_best" else None)
                res[label]["hue"] = hue_error(orig, out, colours)
            rows.append(res)
            print(f"{device:18} {photo:18} " + "  ".join(
                f"{k} {res[k]['de2000']:5.2f}" for k in
                ["ht_fs", "ht_dbs", "ht_abs", "ed_fs", "ed_best"] if k in res), flush=True)
    print()
    calls = all("ht_fs_call_s" in r for r in rows)
    print("| panel | halftone FS | halftone DBS | halftone absolute | epaper-dithering FS |"
          " epaper-dithering best | FS time ht / ed | DBS time ht / ed |"
          + (" FS in the call ht / ed | DBS in the call ht / ed |" if calls else ""))
    print("|---|---:|---:|---:|---:|---:|---:|---:|" + ("---:|---:|" if calls else ""))
    for device in a.panels.split(","):
        rs = [r for r in rows if r["device"] == device]
        if not rs:
            continue
        mean = lambda k: (sum(r[k]["de2000"] for r in rs) / len(rs)  # noqa: E731
                          if k in rs[0] else float("nan"))
        mt = lambda k: (sum(r[k + "_s"] for r in rs) / len(rs)  # noqa: E731
                        if k + "_s" in rs[0] else float("nan"))
        print(f"| {device} | {mean('ht_fs'):.2f} | {mean('ht_dbs'):.2f} | {mean('ht_abs'):.2f} |"
              f" {mean('ed_fs'):.2f} | {mean('ed_best'):.2f} |"
              f" {mt('ht_fs')*1000:.0f} / {mt('ed_fs')*1000:.0f} ms |"
              f" {mt('ht_dbs')*1000:.0f} / {mt('ed_best')*1000:.0f} ms |"
              + (f" {mt('ht_fs_call')*1000:.1f} / {mt('ed_fs')*1000:.1f} ms"
                 f" ({mt('ed_fs') / mt('ht_fs_call'):.1f}×) |"
                 f" {mt('ht_dbs_call')*1000:.0f} / {mt('ed_best')*1000:.0f} ms |" if calls else ""))
    print()
    print("| panel | hue error ht FS | ht DBS | ht absolute | ed FS | ed best |")
    print("|---|---:|---:|---:|---:|---:|")
    for device in a.panels.split(","):
        rs = [r for r in rows if r["device"] == device]
        if rs:
            hm = lambda k: (sum(r[k]["hue"] for r in rs) / len(rs)  # noqa: E731
                            if k in rs[0] else float("nan"))
            print(f"| {device} | " + " | ".join(f"{hm(k):.1f}" for k in
                  ["ht_fs", "ht_dbs", "ht_abs", "ed_fs", "ed_best"]) + " |")
    if a.neutral_black:
        print()
        print("| panel | our DBS, black per channel / neutral |"
              " epaper-dithering best, per channel / neutral |")
        print("|---|---:|---:|")
        for device in a.panels.split(","):
            rs = [r for r in rows if r["device"] == device]
            if rs:
                nm = lambda k, f: sum(r[k][f] for r in rs) / len(rs)  # noqa: E731
                print(f"| {device} | {nm('ht_dbs', 'de2000'):.2f} /"
                      f" {nm('ht_dbs', 'de2000_neutral'):.2f} |"
                      f" {nm('ed_best', 'de2000'):.2f} / {nm('ed_best', 'de2000_neutral'):.2f} |")
    print()
    print(f"Worst {a.worst} photos a panel (our DBS minus epaper-dithering's best, CIEDE2000):")
    for device in a.panels.split(","):
        rs = sorted((r for r in rows if r["device"] == device),
                    key=lambda r: r["ed_best"]["de2000"] - r["ht_dbs"]["de2000"])
        print(f"  {device}: " + ", ".join(
            f"{r['photo']} {r['ht_dbs']['de2000']:.2f}/{r['ed_best']['de2000']:.2f}"
            for r in rs[: a.worst]))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
