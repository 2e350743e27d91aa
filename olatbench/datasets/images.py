"""Image files through OpenImageIO (EXR, HDR, PNG, JPEG, TIFF), NumPy ``.npy`` arrays, and resizing.

Reads return float32 (H, W, C): 8-bit and 16-bit integers are normalised to [0, 1], half and float
data are returned as stored. A ``.npy`` holds the pixels themselves, (H, W) or (H, W, C) (the
NRHints loader reads ``file_ext: ".npy"`` frames with ``np.load``, data/data_parser.py:92-93), and
is returned as stored. OpenImageIO is imported on first use so that ``import olatbench.datasets``
needs numpy alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np

from olatbench.atomic import atomic_path
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.files import require_file, require_utf8_name

BitDepth = Literal["uint8", "uint16", "half", "float"]


def _oiio():
    try:
        import OpenImageIO as oiio
    except ImportError as error:  # pragma: no cover - exercised only without the dependency
        raise ImportError("reading images needs OpenImageIO: pip install OpenImageIO") from error
    return oiio


def _read_config(oiio):
    """Read alpha as stored: OpenImageIO would otherwise premultiply PNG/TIFF colour on read."""
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    return config


def read_image(path: str | Path) -> np.ndarray:
    """Decode an image file to float32 (H, W, C); raise `DatasetError` naming the file on
    failure."""
    return _decode(Path(path))[0]


def read_channels(path: str | Path) -> dict[str, np.ndarray]:
    """Decode an image file to {channel name: float32 (H, W)} (e.g. an EXR with named AOV
    channels)."""
    pixels, names = _decode(Path(path))
    return {name: pixels[..., i] for i, name in enumerate(names)}


def check_image_file(path: Path) -> None:
    """Raise `DatasetError` naming ``path`` unless it is a readable file with a name OpenImageIO can
    open (missing, a folder, a symbolic link loop and a name that is not UTF-8 each say so)."""
    require_file(path, "image file")
    require_utf8_name(path)


_CHANNELS = {1: ["Y"], 2: ["Y", "A"], 3: ["R", "G", "B"], 4: ["R", "G", "B", "A"]}


def _load_npy(path: Path, mmap: bool = False) -> np.ndarray:
    """The (H, W, C) array of a ``.npy`` image (C in 1-4); `DatasetError` naming the file
    otherwise."""
    try:
        array = np.load(path, mmap_mode="r" if mmap else None, allow_pickle=False)
    except (OSError, ValueError) as error:
        raise DatasetError(f"cannot read the array ({error})", path=path) from None
    if array.ndim == 2:
        array = array[..., None]
    if (
        array.ndim != 3
        or array.shape[2] not in _CHANNELS
        or not np.issubdtype(array.dtype, np.number)
    ):
        raise DatasetError(
            f"expected an image array (H, W) or (H, W, 1-4) of numbers, found {array.dtype} "
            f"{array.shape}",
            path=path,
        )
    return array


def _decode(path: Path) -> tuple[np.ndarray, list[str]]:
    """Pixels (H, W, C) float32 and channel names of one image file."""
    check_image_file(path)
    if path.suffix.lower() == ".npy":
        pixels = np.asarray(_load_npy(path), dtype=np.float32)
        return pixels, list(_CHANNELS[pixels.shape[2]])
    oiio = _oiio()
    image_input = oiio.ImageInput.open(str(path), _read_config(oiio))
    if image_input is None:
        raise DatasetError(f"cannot open image ({oiio.geterror() or 'unknown format'})", path=path)
    try:
        spec = image_input.spec()
        pixels = image_input.read_image(0, 0, 0, spec.nchannels, "float")
        error = image_input.geterror()
    finally:
        image_input.close()
    if pixels is None or error:
        raise DatasetError(f"corrupt or truncated image ({error or 'decode failed'})", path=path)
    pixels = np.asarray(pixels, dtype=np.float32)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    if pixels.shape[:2] != (spec.height, spec.width):
        raise DatasetError(
            f"decoded size {pixels.shape[:2]} differs from header {(spec.height, spec.width)}",
            path=path,
        )
    return pixels, list(spec.channelnames)


def image_size(path: str | Path) -> tuple[int, int]:
    """(width, height) from the file header, without decoding the pixels."""
    path = Path(path)
    check_image_file(path)
    if path.suffix.lower() == ".npy":
        height, width = _load_npy(path, mmap=True).shape[:2]
        return int(width), int(height)
    oiio = _oiio()
    image_input = oiio.ImageInput.open(str(path))
    if image_input is None:
        raise DatasetError(
            f"cannot open image ({oiio.geterror() or 'missing or unknown format'})", path=path
        )
    try:
        spec = image_input.spec()
        return int(spec.width), int(spec.height)
    finally:
        image_input.close()


_OIIO_TYPES = {"uint8": "uint8", "uint16": "uint16", "half": "half", "float": "float"}


def write_image(
    path: str | Path,
    pixels: np.ndarray,
    bit_depth: BitDepth | None = None,
    channel_names: Sequence[str] | None = None,
) -> Path:
    """Write float (H, W, C) or (H, W) pixels atomically, as given; integer formats expect [0, 1]
    and round.

    The default bit depth is ``half`` for ``.exr``/``.hdr`` and ``uint8`` otherwise.
    """
    path = Path(path)
    pixels = np.asarray(pixels, dtype=np.float32)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    if not np.all(np.isfinite(pixels)):
        raise ValueError(f"{path}: refusing to write non-finite pixel values")
    suffix = path.suffix.lower()
    if bit_depth is None:
        bit_depth = "half" if suffix in (".exr", ".hdr") else "uint8"
    if bit_depth in ("uint8", "uint16"):
        peak = 255.0 if bit_depth == "uint8" else 65535.0
        pixels = np.rint(np.clip(pixels, 0.0, 1.0) * peak) / peak
    oiio = _oiio()
    height, width, channels = pixels.shape
    spec = oiio.ImageSpec(width, height, channels, _OIIO_TYPES[bit_depth])
    if channel_names is not None:
        if len(channel_names) != channels:
            raise ValueError(f"{path}: {len(channel_names)} channel names for {channels} channels")
        spec.channelnames = tuple(channel_names)
    spec.attribute("DateTime", "")  # no timestamp: the same pixels give the same bytes
    if suffix == ".exr":
        spec.attribute("compression", "zip")
    else:
        # pixels are written as given, never un-premultiplied
        spec.attribute("oiio:UnassociatedAlpha", 1)
    with atomic_path(path) as temporary:
        output = oiio.ImageOutput.create(str(temporary))
        if output is None or not output.open(str(temporary), spec):
            raise OSError(f"{path}: cannot write image ({oiio.geterror()})")
        ok = output.write_image(np.ascontiguousarray(pixels))
        output.close()
        if not ok:
            raise OSError(f"{path}: cannot write image ({output.geterror()})")
    return path


HALF_MANTISSA_BITS = 10


def round_half_mantissa(pixels: np.ndarray, bits: int) -> np.ndarray:
    """Float32 pixels that are half floats with only ``bits`` of their 10 mantissa bits (round to
    nearest, ties away from zero, on the half value): written as ``half`` they keep these values
    exactly, and the files compress better. The relative error is at most ``2^-(bits+1)`` more than
    half's own (``2^-11``); non-finite values and those that would round past half's largest finite
    value are refused."""
    if not 0 <= bits <= HALF_MANTISSA_BITS:
        raise ValueError(f"a half float has 0 to {HALF_MANTISSA_BITS} mantissa bits, not {bits}")
    half = np.asarray(pixels, dtype=np.float32).astype(np.float16)
    if bits == HALF_MANTISSA_BITS:
        return half.astype(np.float32)
    code = half.view(np.uint16).astype(np.uint32)
    sign, magnitude = code & 0x8000, code & 0x7FFF
    drop = HALF_MANTISSA_BITS - bits
    # a carry into the exponent rounds up correctly
    magnitude = ((magnitude + (1 << (drop - 1))) >> drop) << drop
    if np.any(magnitude >= 0x7C00):
        raise ValueError("cannot round non-finite or too large values to a half float")
    return (sign | magnitude).astype(np.uint16).view(np.float16).astype(np.float32)


def resize_image(pixels: np.ndarray, width: int, height: int) -> np.ndarray:
    """Resize float (H, W, C) pixels to (height, width, C) with area averaging (``cv2.INTER_AREA``).

    Area averaging is what the official pipelines use for downscaling; for upscaling it
    behaves like bilinear interpolation. Channels beyond 4 are resized in groups.
    """
    import cv2

    pixels = np.asarray(pixels, dtype=np.float32)
    if pixels.shape[1] == width and pixels.shape[0] == height:
        return pixels
    squeeze = pixels.ndim == 2
    if squeeze:
        pixels = pixels[..., None]
    parts = [
        cv2.resize(pixels[..., i : i + 4], (width, height), interpolation=cv2.INTER_AREA)
        for i in range(0, pixels.shape[2], 4)
    ]
    parts = [p[..., None] if p.ndim == 2 else p for p in parts]
    resized = np.concatenate(parts, axis=2)
    return resized[..., 0] if squeeze else resized
