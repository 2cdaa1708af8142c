"""halftone: continuous-tone images to halftones, on the same Rust core as the command line.

Error diffusion, ordered and pattern dithering, direct binary search and AM screens, all in
linear light; palettes for e-paper panels; CMYK plates; and the printer languages (PDF,
PostScript, PCL, ESC/POS, ZPL).

    >>> import halftone
    >>> r = halftone.convert("photo.jpg", fit="800x480", palette="epaper-7")
    >>> r.array.shape, r.to_pil().mode
    >>> printer.write(halftone.convert("photo.jpg", preset="thermal-203").encode("escpos"))

Keyword arguments are the command line's flags with underscores (``--dot-gain 15`` is
``dot_gain=15``; ``--no-serpentine`` is ``serpentine=False``; ``--no-linearize`` is
``linearize=False``). Errors are ``ValueError`` (bad values, undecodable data), ``TypeError``
(wrong kinds of argument) and ``OSError`` (files), with the command line's messages.
The work runs without the GIL: threads halftone in parallel.
"""

from __future__ import annotations

import io
import json
import os
from typing import Any, Dict, Iterator, List, Optional, Tuple, Union

import numpy as np

from . import _halftone

__all__ = [
    "Result",
    "Clip",
    "convert",
    "convert_to_bytes",
    "compare",
    "lists",
    "methods",
    "kernels",
    "palettes",
    "devices",
    "device",
    "masks",
    "presets",
    "spots",
    "formats",
]

#: The ink of each CMYK plate, in plate order.
INKS = ("cyan", "magenta", "yellow", "black")


def lists() -> Dict[str, Any]:
    """Every list of names the library accepts, as the command line's ``halftone options
    --json`` and the page show them: ``methods``, ``kernels``, ``palettes``, ``masks``,
    ``spots``, ``formats``, ``intents``, ``devices``, ``presses``, ``colors``, ``contents``
    and ``presets`` (pairs of name and description)."""
    return json.loads(_halftone.lists_json())


def methods() -> List[str]:
    """The halftoning methods: threshold, pattern, ordered, diffuse, dbs, screen."""
    return lists()["methods"]


def kernels() -> List[str]:
    """The built-in error-diffusion kernels (``kernel=``), ``tded`` included."""
    return lists()["kernels"]


def palettes() -> List[str]:
    """The built-in palettes (``palette=``)."""
    return lists()["palettes"]


def devices() -> Dict[str, str]:
    """The built-in e-paper panel profiles (``device=``): name → description."""
    return _halftone.devices()


def device(name: Union[str, "os.PathLike[str]"]) -> Dict[str, Any]:
    """One e-paper panel profile, a built-in name or a profile file, as a dict: ``name``,
    ``description``, ``width`` and ``height`` (pixels, in the panel's scan order), ``ppi``,
    ``viewing_distance_cm``, ``rotation`` (degrees clockwise), ``colours`` ("measured",
    "estimated" or "nominal": how far the ink colours can be trusted), ``source``,
    ``encodings`` (the buffer formats its firmware takes, preferred first), ``bits`` (a pixel
    of the packed buffer) and ``inks``: in the panel's index order, each a dict of ``name``,
    ``code`` (the firmware's value), ``nominal`` and ``shown`` (the (r, g, b) the driver
    expects and the one the panel shows). ``halftone devices list`` shows the same."""
    return _halftone.device(os.fspath(name))


def masks() -> List[str]:
    """The built-in masks of the pattern and ordered methods (``mask=``)."""
    return lists()["masks"]


def presets() -> Dict[str, str]:
    """The built-in printer presets (``preset=``), name to description."""
    return dict(lists()["presets"])


def spots() -> List[str]:
    """The spot functions of the screen method (``spot=``)."""
    return lists()["spots"]


def formats() -> List[str]:
    """The output formats of ``Result.encode`` and ``Result.save``."""
    return lists()["formats"]


def _image(image: Any, linear: bool, max_pixels: Any = None) -> Tuple[Any, bool]:
    """The input as the native module takes it: a path, bytes, or a uint8/uint16 array.
    An array is held to ``max_pixels`` (else the default limit) before it is converted."""
    if isinstance(image, (str, os.PathLike)):
        return os.fspath(image), linear
    if isinstance(image, (bytes, bytearray, memoryview)):
        data = bytes(image)
        if not data:
            raise ValueError("the image bytes are empty")
        return data, linear
    if hasattr(image, "read") and callable(image.read):
        # A file object: read it whole (a closed file raises ValueError here).
        if getattr(image, "closed", False):
            raise ValueError("cannot read the image: the file is closed")
        data = image.read()
        if isinstance(data, str):
            raise TypeError("the file is open in text mode; open it with 'rb'")
        if not data:
            raise ValueError("the file gave no bytes")
        return bytes(data), linear
    if _is_pil(image):
        return _from_pil(image), linear
    if isinstance(image, np.ndarray):
        limit = max_pixels if isinstance(max_pixels, int) and max_pixels > 0 else None
        return _from_array(image, linear, limit), linear
    raise TypeError(
        "expected a path, bytes of an image file, a binary file, a Pillow image or a numpy "
        f"array; got {type(image).__name__}"
    )


def _is_pil(obj: Any) -> bool:
    mod = type(obj).__module__ or ""
    return mod.startswith("PIL.") and hasattr(obj, "mode") and hasattr(obj, "size")


def _from_pil(img: Any) -> np.ndarray:
    mode = img.mode
    if mode in ("L", "RGB", "RGBA", "LA"):
        pass
    elif mode == "1":
        img = img.convert("L")
    elif mode in ("I;16", "I;16B", "I;16L"):
        return np.asarray(img).astype(np.uint16)
    elif mode == "P":
        img = img.convert("RGBA" if "transparency" in img.info else "RGB")
    elif mode == "PA":
        img = img.convert("RGBA")
    else:
        # CMYK, YCbCr, LAB, HSV, I, F: Pillow's own conversion to sRGB.
        img = img.convert("RGB")
    return np.asarray(img)


def _check_array_size(a: np.ndarray, limit: Optional[int], sample_bytes: int) -> None:
    """The limits a file meets, from the shape alone (nothing read or copied): at most
    ``limit`` pixels, and the samples made of it within 1 byte a pixel of the limit (at
    least 64 MiB), as the native module checks uint8 and uint16 arrays."""
    max_pixels = limit if limit is not None else _halftone.MAX_PIXELS
    h, w = int(a.shape[0]), int(a.shape[1])
    c = int(a.shape[2]) if a.ndim == 3 else 1
    if h * w > max_pixels:
        raise ValueError(
            f"the image array is {w}x{h} = {h * w} pixels, over the limit of {max_pixels} "
            "(raise it with `max_pixels`)"
        )
    budget = max(max_pixels, 64 << 20)
    if h * w * c * sample_bytes > budget:
        raise ValueError(
            f"the image array is {w}x{h} pixels of {c} samples of {sample_bytes} byte(s): over "
            f"the limit of {budget} bytes of samples that `max_pixels` {max_pixels} sets (1 byte "
            "a pixel of it, as for a decoded file; raise `max_pixels`)"
        )


# Rows of a float array converted at a time: the float64 temporaries stay small.
_ROWS = 256


def _from_array(a: np.ndarray, linear: bool, limit: Optional[int] = None) -> np.ndarray:
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (1, 2, 3, 4)):
        raise ValueError(
            "an image array must be HxW (grey), HxWx3 (RGB) or HxWx4 (RGBA); "
            f"this one has shape {a.shape}"
        )
    if a.size == 0:
        raise ValueError(f"the image array is empty (shape {a.shape})")
    if a.dtype == np.uint8 or a.dtype == np.uint16:
        # Checked by the native module, before it reads or copies anything.
        return a
    if a.dtype.kind == "f":
        _check_array_size(a, limit, 2)
        # Band by band: a view (strided, zero strides) is never copied whole as floats.
        out = np.empty(a.shape, dtype=np.uint16)
        bad, lo, hi = 0, 1.0, 0.0
        for y in range(0, a.shape[0], _ROWS):
            band = a[y : y + _ROWS].astype(np.float64)
            finite = np.isfinite(band)
            if not finite.all():
                bad += int(np.count_nonzero(~finite))
                continue
            lo, hi = min(lo, float(band.min())), max(hi, float(band.max()))
            # Clipped only so that the cast is defined; values outside 0..1 are refused below.
            out[y : y + _ROWS] = np.rint(np.clip(band, 0.0, 1.0) * 65535.0)
        if bad:
            raise ValueError(f"the float image holds {bad} NaN or infinite values")
        if lo < 0.0 or hi > 1.0:
            raise ValueError(
                f"a float image must hold values from 0 to 1; this one goes from {lo:g} to {hi:g}"
            )
        # 16-bit codes keep the precision of the floats well beyond what the methods see.
        return out
    if a.dtype == np.bool_:
        _check_array_size(a, limit, 1)
        return np.where(a, np.uint8(255), np.uint8(0))
    raise TypeError(
        f"an image array must be uint8, uint16 or float (0 to 1); this one is {a.dtype}"
    )


class Result:
    """A halftone: level (or palette) indices, ready to be encoded in any format.

    ``array`` holds the indices as uint8 (0 = darkest, full ink): HxW for grey or a palette,
    HxWx3 for ``color="rgb"``, 4xHxW for CMYK plates (``plates`` gives them by ink).
    """

    __slots__ = ("_native", "_array")

    def __init__(self, native: Any):
        self._native = native
        self._array: Optional[np.ndarray] = None

    @property
    def array(self) -> np.ndarray:
        """Level indices (or palette indices), uint8; see the class docstring for shapes."""
        if self._array is None:
            self._array = self._native.levels_array()
            self._array.flags.writeable = False
        return self._array

    @property
    def width(self) -> int:
        """Width in pixels."""
        return self._native.width

    @property
    def height(self) -> int:
        """Height in pixels."""
        return self._native.height

    @property
    def levels(self) -> int:
        """Output levels a pixel per channel (2 = bilevel)."""
        return self._native.levels

    @property
    def kind(self) -> str:
        """``"gray"``, ``"rgb"``, ``"palette"`` or ``"cmyk"``."""
        return self._native.kind

    @property
    def palette(self) -> Optional[List[Tuple[int, int, int]]]:
        """The palette's colours (index → (r, g, b)), or None."""
        return self._native.palette

    @property
    def dpi(self) -> Optional[float]:
        """The resolution recorded in the output (``dpi``, else a ``device``'s ppi), or None."""
        return self._native.dpi

    @property
    def plates(self) -> Optional[Dict[str, np.ndarray]]:
        """CMYK: the four plates by ink name (HxW level indices, 0 = full ink); else None."""
        if self.kind != "cmyk":
            return None
        return {ink: self.array[i] for i, ink in enumerate(INKS)}

    @property
    def preview(self) -> Optional[np.ndarray]:
        """CMYK: how the printed plates look, an HxWx3 uint8 sRGB array; else None."""
        return self._native.preview_array()

    def to_rgb(self) -> np.ndarray:
        """The halftone as it displays: an HxW (grey) or HxWx3 (colour) uint8 array."""
        a = self.array
        if self.kind == "palette":
            lut = np.array(self.palette, dtype=np.uint8)
            return lut[a]
        if self.kind == "cmyk":
            p = self.preview
            if p is None:
                raise ValueError("this CMYK result has no preview (convert with preview=True)")
            return p
        return _display(a, self.levels)

    def to_pil(self) -> Any:
        """A Pillow image: mode "1" for bilevel grey, "L" for grey levels, "P" for a
        palette, "RGB" for colour, and the preview for CMYK."""
        from PIL import Image

        if self.kind == "palette":
            im = Image.frombytes("P", (self.width, self.height), self.array.tobytes())
            flat = [c for rgb in self.palette for c in rgb]
            im.putpalette(flat)
            return im
        rgb = self.to_rgb()
        if self.kind == "gray" and self.levels == 2:
            return Image.fromarray(rgb).convert("1", dither=Image.Dither.NONE)
        return Image.fromarray(rgb)

    def encode(self, format: str, plate: Optional[str] = None) -> bytes:
        """The halftone as the bytes of a file: ``pbm pgm ppm png tiff bmp pdf ps pcl escpos
        zpl``, or for a ``device`` its panel buffer (``raw``/``bin``, ``h`` a C header,
        ``planes``, ``nibbles``), exactly as the command line writes them with the same
        options. CMYK: "pdf" holds all four plates; other formats encode one ``plate``
        ("cyan" … "black")."""
        return self._native.encode(format, plate)

    def save(self, path: Union[str, "os.PathLike[str]"], format: Optional[str] = None) -> None:
        """Writes the file atomically, in ``format`` or the one of the extension. CMYK
        writes one PDF, or NAME-cyan.EXT … NAME-black.EXT."""
        self._native.save(os.fspath(path), format)

    def _repr_png_(self) -> bytes:
        if self.kind == "cmyk":
            from PIL import Image

            buf = io.BytesIO()
            Image.fromarray(self.to_rgb()).save(buf, format="PNG")
            return buf.getvalue()
        return self.encode("png")

    def __repr__(self) -> str:
        return f"<halftone.Result {self.width}x{self.height} {self.kind} levels={self.levels}>"


def _display(a: np.ndarray, levels: int) -> np.ndarray:
    """Levels to display codes, as the PNG encoder writes them (sRGB codes of the
    levels' reflectance: evenly spaced in linear light)."""
    if levels == 2:
        return np.where(a > 0, np.uint8(255), np.uint8(0))
    lin = np.arange(levels, dtype=np.float64) / (levels - 1)
    srgb = np.where(lin <= 0.0031308, lin * 12.92, 1.055 * np.power(lin, 1 / 2.4) - 0.055)
    lut = np.rint(srgb * 255.0).astype(np.uint8)
    return lut[a]


def convert(
    image: Any,
    *,
    method: Optional[str] = None,
    kernel: Optional[str] = None,
    levels: Optional[int] = None,
    palette: Optional[str] = None,
    device: Optional[str] = None,
    mask: Optional[str] = None,
    threshold: Union[None, float, int, str] = None,
    lpi: Union[None, float, str] = None,
    angle: Optional[float] = None,
    spot: Optional[str] = None,
    color: Optional[str] = None,
    preset: Optional[str] = None,
    presets: Optional[str] = None,
    dpi: Optional[float] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
    fit: Union[None, str, Tuple[int, int]] = None,
    size: Optional[str] = None,
    rotate: Union[None, str, int] = None,
    linear: bool = False,
    **options: Any,
) -> Result:
    """Halftones ``image`` and returns a :class:`Result`.

    image: a path, the bytes of an image file (PNG, JPEG, TIFF, BMP, GIF, WebP, PNM), a binary
        file object, a Pillow image, or a numpy array: HxW grey, HxWx3 RGB or HxWx4 RGBA
        (composited over white in linear light), uint8, uint16 or float in 0..1. Codes are
        sRGB-encoded unless ``linear=True`` says they are linear light.
    linear: the array's or file's codes are linear light, not sRGB.
    threads: worker threads for this call's own parallel work (default: every core). Give 1
        when calls already run side by side (a thread per request, a process pool), so that they
        do not share the cores twice over. The bytes are the same whatever the number.
    preset: a printer preset (``presets()``); arguments given here win over it. presets: a
        TOML file of presets added to the built-in ones.

    Every option of ``halftone convert`` is a keyword, its flag with underscores
    (``--dot-gain 15`` is ``dot_gain=15``; ``--no-serpentine`` is ``serpentine=False``). An
    option the chosen method or format does not read is refused, as on the command line.
    ``halftone options`` lists the same; ``lists()`` gives the built-in names.

    Options:
    """
    kw = dict(
        method=method,
        kernel=kernel,
        levels=levels,
        palette=palette,
        device=device,
        mask=mask,
        threshold=threshold,
        lpi=lpi,
        angle=angle,
        spot=spot,
        color=color,
        preset=preset,
        presets=presets,
        dpi=dpi,
        width=width,
        height=height,
        fit=fit,
        size=size,
        rotate=rotate,
    )
    kw.update(options)
    kw = {k: (os.fspath(v) if isinstance(v, os.PathLike) else v) for k, v in kw.items() if v is not None}
    src, linear = _image(image, linear, kw.get("max_pixels"))
    return Result(_halftone.convert(src, linear, **kw))


class Clip:
    """A clip halftoned a frame at a time, as ``halftone convert clip.gif -o out.gif`` does:
    ordered dithering, blue noise and the other masks stay put, and ``method="diffuse"``
    re-decides a dot only where the picture changed enough for the eye to see
    (``temporal="frame"``: every frame afresh). The same frames and options give the command
    line's bytes.

        >>> clip = halftone.Clip(method="diffuse", width=320)
        >>> for result in clip.map(frames):      # numpy arrays, every one the same size
        ...     panel.show(result.array)

    Options are :func:`convert`'s keywords.
    """

    __slots__ = ("_native",)

    def __init__(self, **options: Any):
        kw = {k: (os.fspath(v) if isinstance(v, os.PathLike) else v) for k, v in options.items() if v is not None}
        self._native = _halftone.Clip(**kw)

    def next(self, frame: Any, *, linear: bool = False) -> "Result":
        """The next frame's halftone. ``frame``: a numpy array (HxW grey, HxWx3 RGB or
        HxWx4 RGBA; uint8, uint16 or float in 0..1) or a Pillow image."""
        if isinstance(frame, (str, os.PathLike, bytes, bytearray, memoryview)):
            raise TypeError("Clip.next: a frame is a numpy array or a Pillow image")
        src, linear = _image(frame, linear)
        return Result(self._native.next(src, linear))

    def map(self, frames: Any, *, linear: bool = False) -> Iterator["Result"]:
        """Each frame's halftone in turn, as the frames come (a generator: one frame held)."""
        for frame in frames:
            yield self.next(frame, linear=linear)


def _options_doc() -> str:
    """The options part of :func:`convert`'s docstring, made from the library's one option
    table, so that it names every option the command line has, with its help."""
    import re
    import textwrap

    options = json.loads(_halftone.options_json())
    names = {}
    for o in options:
        names[o["flag"][2:]] = o["name"]
        for alias in o["aliases"]:
            names[alias.replace("_", "-")] = alias

    def keywords(text: str) -> str:
        # The help is the command line's: its flags are written as the keywords here.
        return re.sub(r"--([a-z][a-z0-9-]*)", lambda m: names.get(m.group(1), m.group(0)), text)

    out = []
    for o in options:
        text = keywords(" ".join(o["help"].split()))
        if o["default"] is not None and "[default" not in text:
            text += f" [default: {o['default']}]"
        if o["choices"] == "fixed":
            text += ". Values: " + ", ".join(o["values"]) + "."
        out.append(
            textwrap.fill(
                text,
                width=92,
                initial_indent=f"    {o['name']}: ",
                subsequent_indent="        ",
                break_on_hyphens=False,
            )
        )
    return "\n".join(out) + "\n    "


convert.__doc__ = (convert.__doc__ or "").rstrip() + "\n" + _options_doc()


def convert_to_bytes(image: Any, format: str, *, linear: bool = False, **options: Any) -> bytes:
    """Halftones ``image`` straight into the bytes of a ``format`` file (the command line's
    streaming road for large files: bands of rows, little memory). Options as
    :func:`convert`; not for CMYK."""
    kw = {k: (os.fspath(v) if isinstance(v, os.PathLike) else v) for k, v in options.items() if v is not None}
    src, linear = _image(image, linear, kw.get("max_pixels"))
    return _halftone.convert_to_bytes(src, format, linear, **kw)


def compare(
    original: Any,
    halftone: Any,
    *,
    dpi: float = 300.0,
    distance: float = 12.0,
    linear: bool = False,
    device: Optional[Union[str, "os.PathLike[str]"]] = None,
) -> Dict[str, Any]:
    """How close ``halftone`` looks to ``original`` at ``distance`` inches when printed at
    ``dpi``: the figures of ``halftone compare`` as a dict (hvs_psnr_db, hvs_mse,
    tone_bias, lstar_rms, plain_psnr_db, scale). ``halftone`` is a :class:`Result` or an
    image file/array; ``original`` any input :func:`convert` takes.

    device: a halftone made for an e-paper panel (a built-in name, see :func:`devices`, or
        a profile file), scored as ``halftone compare --device`` scores it: as a viewer
        adapted to the panel's white and black sees it, S-CIELAB at the panel's pixels a
        degree (``dpi`` and ``distance`` are the profile's). The dict holds ``de2000``
        (mean CIEDE2000), ``de76`` (mean ΔE*ab), ``lightness_ratio`` (mean L*, displayed
        over original), ``pixels_per_degree`` and ``device`` (its name). The halftone is
        read in the inks' measured colours: a :class:`Result` as its PNG with the default
        ``ink_colours``, a file as ``convert(..., device=...)`` writes it by default. Both
        images must be the same size (give ``convert`` a size to keep the original's).
    """
    src, linear = _image(original, linear)
    if isinstance(halftone, Result):
        ht = halftone._native
    else:
        ht, _ = _image(halftone, False)
    dev = None if device is None else os.fspath(device)
    return _halftone.compare(src, ht, float(dpi), float(distance), linear, dev)
