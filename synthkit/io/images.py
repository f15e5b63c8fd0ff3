"""Reading and writing images: the only place images touch files.

Images are ``float32 (H, W)`` or ``(H, W, C)`` arrays in [0, 1] inside synthkit. 8- and 16-bit
PNG, JPEG and TIFF files in grey, RGB or RGBA are read; writing turns floats into 8-bit (or keeps
``uint16`` arrays 16-bit).

Transparency. synthkit's methods work on colour only, so :func:`load_image` in ``"rgb"`` and
``"gray"`` mode flattens an image with an alpha channel the way an image viewer shows it on a
white page and the way ``magick -flatten`` or GIMP's "Remove Alpha Channel" do: every pixel is
composited over white, ``rgb = a * rgb + (1 - a)``, before the grey conversion. A fully opaque
alpha channel (every pixel at the maximum value) changes nothing. When some pixels are not
opaque, one warning says how many were composited. ``"any"`` mode returns the file's channels,
alpha included and unchanged (straight, not premultiplied).

Decoder messages. libjpeg, libpng, libtiff and OpenCV print their warnings on the process's
stderr (fd 2), past Python. :func:`load_image` and :func:`save_image` capture fd 2 during the
OpenCV call (:mod:`synthkit.io._capture`), with OpenCV's log level held at WARNING so that its
INFO/DEBUG lines (which go to stdout) are not printed either. Nothing a decoder prints reaches
the terminal. The captured lines are read by this rule:

- metadata warnings are benign and ignored (logged at DEBUG level only): libpng warnings about an
  ancillary chunk (colour profile ``iCCP``, ``sRGB``, ``cHRM``, ``gAMA``, text and time chunks
  ...), libtiff's "Unknown field with tag" and "ASCII value for tag", EXIF warnings, and OpenCV's
  own "can't open/read file" line (synthkit says what is wrong with the file itself);
- every other line is a decoder warning or error about the pixel data (libjpeg's "Premature end
  of JPEG file" or "Corrupt JPEG data: ...", "libpng error: ...", a libtiff error, an OpenCV
  decoder warning): the image is corrupt, even if OpenCV returned pixels (libjpeg fills a
  truncated image with grey), and :func:`load_image` raises
  ``InputError("<path>: corrupt image: <first such line>")`` (exit code 3).
"""

from __future__ import annotations

import contextlib
import logging
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from synthkit.errors import InputError
from synthkit.io._capture import captured_stderr, check_readable
from synthkit.io.atomic import write_bytes_atomic
from synthkit.io.probe import image_shape

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")

IMAGE_MAX_PIXELS = 1 << 28
"""Largest image :func:`load_image` decodes (16384 x 16384): its header is read first, and a larger
image is refused before any pixel is decoded (a 2.6 MB PNG can declare 30000 x 30000 pixels)."""


def load_image(path: Path | str, *, mode: Literal["rgb", "gray", "any"] = "rgb") -> np.ndarray:
    """Read an image as float32 in [0, 1].

    Parameters
    ----------
    path : PNG, JPEG or TIFF file, 8 or 16 bit, grey, RGB or RGBA.
    mode : "rgb" gives ``(H, W, 3)`` (grey replicated); "gray" gives ``(H, W)`` luminance
        (Rec. 601 weights); in both an alpha channel is composited over white (module docstring).
        "any" keeps the file's channels (``(H, W)``, or 2 to 4 channels, alpha last, unchanged).

    Raises
    ------
    InputError : missing, unreadable (permission denied, a folder), empty, corrupt (any decoder
        warning about the pixel data, see the module docstring) or non-finite image.
    """
    path = Path(path)
    if check_readable(path, "image") == 0:
        raise InputError(f"{path}: image file is empty (0 bytes)")
    shape = image_shape(path)
    if shape is not None and shape[0] * shape[1] > IMAGE_MAX_PIXELS:
        raise InputError(f"{path}: image is {shape[1]}x{shape[0]} ({shape[0] * shape[1]:.2g} pixels); "
                         f"images over {IMAGE_MAX_PIXELS:.2g} pixels are refused")
    with _opencv_captured() as lines:
        raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    problem = _decoder_problem(lines, path)
    if problem is not None:
        raise InputError(f"{path}: corrupt image: {problem}")
    if raw is None:
        raise InputError(f"{path}: cannot read image (corrupt or unsupported format)")
    if raw.size == 0 or raw.shape[0] == 0 or raw.shape[1] == 0:
        raise InputError(f"{path}: image is empty")
    if raw.dtype == np.uint8:
        img = raw.astype(np.float32) / 255.0
    elif raw.dtype == np.uint16:
        img = raw.astype(np.float32) / 65535.0
    else:
        img = raw.astype(np.float32)
        if not np.isfinite(img).all():
            raise InputError(f"{path}: image has non-finite values")
        img = np.clip(img, 0.0, 1.0)
    if img.ndim == 3 and img.shape[2] in (3, 4):
        img = img[..., [2, 1, 0, 3]] if img.shape[2] == 4 else img[..., ::-1]
    if mode == "any":
        return np.ascontiguousarray(img)
    if img.ndim == 3 and img.shape[2] in (2, 4):
        img = _over_white(img, path)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    if mode == "rgb":
        if img.ndim == 2:
            img = np.repeat(img[..., None], 3, axis=2)
        return np.ascontiguousarray(img)
    if img.ndim == 3:
        img = img @ np.array([0.299, 0.587, 0.114], dtype=np.float32)
    return np.ascontiguousarray(img.astype(np.float32))


def save_image(path: Path | str, img: np.ndarray) -> None:
    """Write ``img`` (H, W[, 3|4]) atomically; floats are clipped to [0, 1] and stored 8-bit."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise ValueError(f"unsupported image format {suffix!r}")
    arr = np.asarray(img)
    if arr.ndim not in (2, 3) or arr.size == 0:
        raise ValueError(f"image must be (H, W) or (H, W, C), got shape {arr.shape}")
    if arr.dtype not in (np.uint8, np.uint16):
        wide = arr.astype(np.float64)  # one float64 copy, then in place
        if not np.isfinite(wide).all():  # the common case skips nan_to_num's slow infinity scans
            np.nan_to_num(wide, copy=False)
        np.clip(wide, 0.0, 1.0, out=wide)
        np.multiply(wide, 255.0, out=wide)
        arr = np.round(wide, out=wide).astype(np.uint8)
    if arr.ndim == 3:
        if arr.shape[2] == 1:
            arr = arr[..., 0]
        elif arr.shape[2] == 3:
            arr = arr[..., ::-1]
        elif arr.shape[2] == 4:
            arr = arr[..., [2, 1, 0, 3]]
        else:
            raise ValueError(f"image must have 1, 3 or 4 channels, got {arr.shape[2]}")
    with _opencv_captured() as lines:
        try:
            ok, encoded = cv2.imencode(suffix, np.ascontiguousarray(arr))
        except cv2.error as exc:
            ok, lines = False, [*lines, str(exc).strip().splitlines()[-1]]
    if not ok:
        said = [_strip_prefix(line) for line in lines]
        raise OSError(f"cannot write image {path}" + (f": {said[0]}" if said else ""))
    for line in lines:
        log.debug("%s: encoder said: %s", path, line)
    try:
        write_bytes_atomic(path, encoded.tobytes())
    except OSError as exc:
        raise OSError(f"cannot write image {path}: {exc.strerror or exc}") from None


def _over_white(img: np.ndarray, path: Path) -> np.ndarray:
    """Colour of ``img (H, W, 4)`` RGBA or ``(H, W, 2)`` grey + alpha (straight alpha) composited
    over white, ``(H, W, 3)`` or ``(H, W)``; one warning if any pixel is not opaque."""
    colour, alpha = img[..., :-1], img[..., -1:]
    if colour.shape[2] == 1:
        colour = colour[..., 0]
        alpha = alpha[..., 0]
    translucent = int(np.count_nonzero(img[..., -1] < 1.0))
    if translucent == 0:
        return colour
    total = img.shape[0] * img.shape[1]
    log.warning(
        "%s: %d of %d pixels are transparent or translucent; composited over white (synthkit uses colour only)",
        path, translucent, total,
    )
    return (colour * alpha + (1.0 - alpha)).astype(np.float32)


@contextlib.contextmanager
def _opencv_captured() -> Iterator[list[str]]:
    """Capture fd 2 (see :func:`~synthkit.io._capture.captured_stderr`) with OpenCV's log level at
    WARNING; the list is filled when the block ends."""
    with captured_stderr() as lines:
        previous = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_WARNING)
        try:
            yield lines
        finally:
            cv2.utils.logging.setLogLevel(previous)


_OPENCV_PREFIX = re.compile(r"^\[\s*[A-Z]+:[^\]]*\]\s*(?:global\s+)?(?:\S+\.\w+:\d+\s+)?(?:\S+\s+)?")
"""OpenCV's log line prefix: ``[ WARN:0@0.039] global grfmt_png.cpp:793 readFromStreamOrBuffer ``."""

_BENIGN = re.compile(
    r"libpng warning: (iCCP|sRGB|cHRM|gAMA|sBIT|bKGD|hIST|pHYs|oFFs|pCAL|sCAL|sPLT|tIME|tEXt|zTXt|iTXt|eXIf|cICP)\b"
    r"|Unknown field with tag|ASCII value for tag"
    r"|exif"
    r"|findDecoder|can't open/read file",
    re.IGNORECASE,
)
"""Captured lines about metadata, or OpenCV's own "cannot open" line: not a sign of corrupt pixels."""


def _strip_prefix(line: str) -> str:
    """A decoder line without its library's prefix (OpenCV's log header, ``libpng error:``, ...)."""
    line = _OPENCV_PREFIX.sub("", line) if line.startswith("[") else line
    for prefix in ("libpng error: ", "libpng warning: ", "TIFF_Error ", "TIFF_Warning "):
        line = line.removeprefix(prefix)
    return line.strip()


def _decoder_problem(lines: list[str], path: Path) -> str | None:
    """The first captured line that says the pixel data is corrupt (module docstring), without its
    library prefix; benign lines are logged at DEBUG level."""
    problem = None
    for line in lines:
        if _BENIGN.search(line):
            log.debug("%s: decoder said (ignored): %s", path, line)
        elif problem is None:
            problem = _strip_prefix(line) or line
    return problem
