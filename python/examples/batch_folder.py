"""A folder of photos → 4-level PNGs for a 4-grey e-ink panel, one process a core.
(Threads work too: the GIL is released while halftoning.)"""
import pathlib
import sys
from concurrent.futures import ProcessPoolExecutor

import halftone

src = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "photos")
dst = pathlib.Path(sys.argv[2] if len(sys.argv) > 2 else "out")


def one(path: pathlib.Path) -> str:
    out = dst / (path.stem + ".png")
    halftone.convert(path, preset="eink-4grey").save(out)
    return out.name


if __name__ == "__main__":
    dst.mkdir(exist_ok=True)
    photos = sorted(p for p in src.iterdir() if p.suffix.lower() in {".jpg", ".jpeg", ".png", ".tif", ".tiff"})
    with ProcessPoolExecutor() as pool:
        for name in pool.map(one, photos):
            print(name)
