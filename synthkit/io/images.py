"""Reading and writing images: the only place images touch files.

Images are ``float32 (H, W)`` or ``(H, W, C)`` arrays in [0, 1] inside synthkit. 8- and 16-bit
PNG, JPEG and TIFF files in grey, RGB or RGBA are read; writing turns floats into 8-bit (or keeps
``uint16`` arrays 16-bit).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from synthkit.errors import InputError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff")


def load_image(path: Path | str, *, mode: Literal["rgb", "gray", "any"] = "rgb") -> np.ndarray:
    """Read an image as float32 in [0, 1].

    Parameters
    ----------
    path : PNG, JPEG or TIFF file, 8 or 16 bit, grey, RGB or RGBA.
    mode : "rgb" gives ``(H, W, 3)`` (alpha dropped, grey replicated); "gray" gives ``(H, W)``
        luminance (Rec. 601 weights); "any" keeps the file's channels (``(H, W)``, 3 or 4).

    Raises
    ------
    InputError : missing, unreadable, empty (zero-sized) image.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: image file not found")
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
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
    if img.ndim == 3:
        img = img[..., [2, 1, 0, 3]] if img.shape[2] == 4 else img[..., ::-1]
    if mode == "any":
        return np.ascontiguousarray(img)
    if img.ndim == 3:
        img = img[..., :3]
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
        arr = np.round(np.clip(np.nan_to_num(arr.astype(np.float64)), 0.0, 1.0) * 255.0).astype(np.uint8)
    if arr.ndim == 3:
        if arr.shape[2] == 1:
            arr = arr[..., 0]
        elif arr.shape[2] == 3:
            arr = arr[..., ::-1]
        elif arr.shape[2] == 4:
            arr = arr[..., [2, 1, 0, 3]]
        else:
            raise ValueError(f"image must have 1, 3 or 4 channels, got {arr.shape[2]}")
    tmp = path.with_name(path.name + ".tmp" + suffix)
    if not cv2.imwrite(str(tmp), np.ascontiguousarray(arr)):
        raise OSError(f"cannot write image {path}")
    os.replace(tmp, path)
