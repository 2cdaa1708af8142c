"""Type stubs of the halftone package."""

import os
from typing import Any, BinaryIO, Dict, List, Literal, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

ImageInput = Union[str, os.PathLike[str], bytes, bytearray, memoryview, BinaryIO, npt.NDArray[Any], Any]
Format = Literal[
    "pbm", "pgm", "ppm", "pnm", "png", "tif", "tiff", "bmp", "pdf", "ps", "pcl", "escpos", "zpl",
    "raw", "bin", "h", "planes", "nibbles",
]

INKS: Tuple[str, str, str, str]

class Result:
    """A halftone: level (or palette) indices, ready to be encoded in any format."""

    @property
    def array(self) -> npt.NDArray[np.uint8]: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def levels(self) -> int: ...
    @property
    def kind(self) -> Literal["gray", "rgb", "palette", "cmyk"]: ...
    @property
    def palette(self) -> Optional[List[Tuple[int, int, int]]]: ...
    @property
    def dpi(self) -> Optional[float]: ...
    @property
    def plates(self) -> Optional[Dict[str, npt.NDArray[np.uint8]]]: ...
    @property
    def preview(self) -> Optional[npt.NDArray[np.uint8]]: ...
    def to_rgb(self) -> npt.NDArray[np.uint8]: ...
    def to_pil(self) -> Any: ...
    def encode(self, format: Format, plate: Optional[Literal["cyan", "magenta", "yellow", "black", "c", "m", "y", "k"]] = None) -> bytes: ...
    def save(self, path: Union[str, os.PathLike[str]], format: Optional[Format] = None) -> None: ...

def convert(
    image: ImageInput,
    *,
    method: Optional[Literal["threshold", "pattern", "ordered", "diffuse", "dbs", "screen"]] = None,
    kernel: Optional[str] = None,
    levels: Optional[int] = None,
    palette: Optional[str] = None,
    device: Optional[str] = None,
    ink_colours: Optional[Literal["measured", "nominal"]] = None,
    mask: Optional[str] = None,
    threshold: Union[None, float, int, str] = None,
    lpi: Union[None, float, str] = None,
    angle: Optional[float] = None,
    spot: Optional[str] = None,
    color: Optional[Literal["gray", "rgb", "cmyk"]] = None,
    preset: Optional[str] = None,
    presets: Optional[Union[str, os.PathLike[str]]] = None,
    dpi: Optional[float] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
    fit: Union[None, str, Tuple[int, int]] = None,
    fit_mode: Optional[Literal["inside", "pad", "cover"]] = None,
    size: Optional[str] = None,
    rotate: Union[None, Literal["auto", "none", "90", "180", "270"], int] = None,
    linear: bool = False,
    threads: Optional[int] = None,
    serpentine: Optional[bool] = None,
    strength: Optional[float] = None,
    seed: Optional[int] = None,
    cell: Optional[Literal["fit", "expand"]] = None,
    linearize: Optional[bool] = None,
    invert: Optional[bool] = None,
    gamma: Optional[float] = None,
    dot_gain: Optional[float] = None,
    transfer: Optional[Union[str, os.PathLike[str]]] = None,
    format: Optional[Format] = None,
    maxval: Optional[int] = None,
    compression: Optional[Literal["g4", "deflate", "lzw", "packbits", "none"]] = None,
    device_levels: Optional[bool] = None,
    page: Optional[str] = None,
    band_rows: Optional[int] = None,
    cut: Optional[bool] = None,
    paper_width: Optional[int] = None,
    zpl_encoding: Optional[Literal["hex", "z64"]] = None,
    max_length: Optional[int] = None,
    content: Optional[Literal["photo", "line-art", "auto"]] = None,
    max_pixels: Optional[int] = None,
    max_memory: Optional[str] = None,
    passes: Optional[int] = None,
    distance: Optional[float] = None,
    tone_correction: Optional[bool] = None,
    hysteresis: Optional[float] = None,
    printer_model: Optional[Literal["ideal", "dot-overlap", "table"]] = None,
    dot_ratio: Optional[float] = None,
    printer_table: Optional[Union[str, os.PathLike[str]]] = None,
    angles: Optional[str] = None,
    press: Optional[str] = None,
    gcr: Optional[float] = None,
    tac: Optional[float] = None,
    separation: Optional[Literal["model", "naive"]] = None,
    icc: Optional[Union[str, os.PathLike[str]]] = None,
    intent: Optional[Literal["perceptual", "relative", "saturation", "absolute"]] = None,
    exposure: Optional[float] = None,
    saturation: Optional[float] = None,
    tone: Optional[Union[float, Literal["auto", "off"]]] = None,
    gamut: Optional[Union[float, Literal["auto", "off"]]] = None,
    preview: Optional[bool] = None,
    preview_block: Optional[int] = None,
    temporal: Optional[Literal["stable", "frame"]] = None,
) -> Result: ...
def convert_to_bytes(image: ImageInput, format: Format, *, linear: bool = False, **options: Any) -> bytes: ...
def compare(
    original: ImageInput,
    halftone: Union[Result, ImageInput],
    *,
    dpi: float = 300.0,
    distance: float = 12.0,
    linear: bool = False,
    device: Optional[Union[str, os.PathLike[str]]] = None,
) -> Dict[str, Any]: ...
def lists() -> Dict[str, Any]: ...
def methods() -> List[str]: ...
def kernels() -> List[str]: ...
def palettes() -> List[str]: ...
def devices() -> Dict[str, str]: ...
def device(name: Union[str, os.PathLike[str]]) -> Dict[str, Any]: ...
def masks() -> List[str]: ...
def presets() -> Dict[str, str]: ...
def spots() -> List[str]: ...
def formats() -> List[str]: ...
