"""Where a run's inputs come from: the files its config names, or objects given in memory.

A pipeline reads every input through an :class:`Inputs` (``inputs.mesh(cfg.input)``,
``inputs.image(item.image)``). From the command line an ``Inputs()`` reads the files; the Python
functions of :mod:`synthkit.api` give an ``Inputs`` that also holds the meshes and images passed
to them, each under the name that stands in the config for it (``<memory:images.0.image>``), so
that one pipeline serves both and nothing is written to read an object given in memory.

Objects taken in memory, and what each reader makes of them:

- a ``trimesh.Trimesh`` or ``trimesh.Scene``: :meth:`Inputs.mesh` gives a copy of the mesh (a
  scene is merged, as :func:`~synthkit.io.meshes.load_mesh` merges a file's scene);
  :meth:`Inputs.asset` reads its UVs, colours and materials (:func:`~synthkit.io.assets.asset_from_trimesh`);
- a ``(V, F)`` pair of arrays: ``V (#V, 3)`` positions and ``F (#F, 3)`` triangles, no appearance;
- an :class:`~synthkit.asset.Asset`: used as it is by :meth:`Inputs.asset`, its geometry by
  :meth:`Inputs.mesh`;
- an image array ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``, ``uint8``, ``uint16`` or float in
  [0, 1]: converted as :func:`~synthkit.io.images.load_image` converts a file's pixels (alpha over
  white, grey replicated to RGB or RGB to Rec. 601 luminance);
- a path: the file is read, as from a config.

The same checks apply as to files, with the same messages, naming the config key instead of the
file (``input: mesh has no faces``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
import trimesh

from synthkit.asset import Asset
from synthkit.errors import InputError
from synthkit.io.assets import asset_from_trimesh, load_asset
from synthkit.io.images import load_image
from synthkit.io.meshes import check_mesh, load_face_labels, load_mesh

__all__ = ["Inputs", "memory_name", "is_memory_object", "LUMINANCE"]

MEMORY_PREFIX = "<memory:"

LUMINANCE = np.array([0.299, 0.587, 0.114], dtype=np.float32)
"""Rec. 601 weights of an RGB image's grey version (as :func:`~synthkit.io.images.load_image`)."""


def memory_name(key: str) -> str:
    """The name that stands in a config for the object given in memory for ``key``
    (``"<memory:images.0.image>"``)."""
    return f"{MEMORY_PREFIX}{key}>"


def is_memory_object(value: object) -> bool:
    """Whether ``value`` is a mesh, an asset, a ``(V, F)`` pair or an image array (not a path,
    number, string or list of numbers)."""
    if isinstance(value, trimesh.Trimesh | trimesh.Scene | Asset | np.ndarray):
        return True
    return (isinstance(value, tuple) and len(value) == 2
            and all(isinstance(part, np.ndarray) for part in value))


class Inputs:
    """The inputs of one run: files, plus objects given in memory under their stand-in names.

    Parameters
    ----------
    objects : stand-in name (:func:`memory_name`) -> the object given for it.

    Attributes
    ----------
    files : the input files the config names (a later save may not write over them).
    """

    def __init__(self, objects: dict[str, object] | None = None):
        self.objects = dict(objects or {})
        self.files: list[Path] = []

    def _given(self, path: Path | str | None) -> tuple[bool, object, str]:
        """(whether ``path`` is a stand-in, the object, the config key it stands for)."""
        name = str(path)
        if name in self.objects:
            return True, self.objects[name], name.removeprefix(MEMORY_PREFIX).removesuffix(">")
        return False, None, name

    def is_memory(self, path: Path | str | None) -> bool:
        """Whether ``path`` stands for an object given in memory."""
        return str(path) in self.objects

    def source(self, path: Path | str) -> str:
        """What a message names an input by: the config key of an object given in memory
        (``"input"``), else the file's path."""
        return self._given(path)[2]

    def mesh(self, path: Path | str, *, process: bool = False) -> trimesh.Trimesh:
        """The mesh at ``path`` (:func:`~synthkit.io.meshes.load_mesh`) or given for it: a copy,
        so that a pipeline may change it; ``process`` merges duplicate vertices as trimesh does."""
        given, obj, key = self._given(path)
        if not given:
            return load_mesh(path, process=process)
        if isinstance(obj, Asset):
            mesh = trimesh.Trimesh(obj.V, obj.F, process=process)
        elif isinstance(obj, tuple):
            V, F = obj
            check_mesh(V, F, source=key)
            mesh = trimesh.Trimesh(np.asarray(V, np.float64), np.asarray(F, np.int64), process=process)
        elif isinstance(obj, trimesh.Scene):
            geoms = [g for g in obj.dump() if isinstance(g, trimesh.Trimesh)]
            if not geoms:
                raise InputError(f"{key}: scene holds no triangle mesh")
            mesh = geoms[0].copy() if len(geoms) == 1 else trimesh.util.concatenate(geoms)
            mesh.metadata["merged_geometries"] = len(geoms)
        elif isinstance(obj, trimesh.Trimesh):
            mesh = obj.copy()
        else:
            raise InputError(f"{key}: expected a mesh, got {type(obj).__name__}")
        check_mesh(mesh.vertices, mesh.faces, source=key)
        mesh.metadata.setdefault("merged_geometries", 1)
        return mesh

    def asset(self, path: Path | str) -> Asset:
        """The asset at ``path`` (:func:`~synthkit.io.assets.load_asset`) or given for it."""
        given, obj, key = self._given(path)
        if not given:
            return load_asset(path)
        if isinstance(obj, Asset):
            check_mesh(obj.V, obj.F, source=key)
            return obj
        if isinstance(obj, tuple):
            mesh = self.mesh(path)
            return asset_from_trimesh(mesh, key)
        if not isinstance(obj, trimesh.Trimesh | trimesh.Scene):
            raise InputError(f"{key}: expected a mesh, got {type(obj).__name__}")
        try:
            asset = asset_from_trimesh(obj, key)
        except ValueError as exc:
            raise InputError(str(exc)) from None
        check_mesh(asset.V, asset.F, source=key)
        return asset

    def image(self, path: Path | str, *, mode: Literal["rgb", "gray", "any"] = "rgb") -> np.ndarray:
        """The image at ``path`` (:func:`~synthkit.io.images.load_image`) or given for it, as
        float32 in [0, 1]: ``(H, W, 3)`` for ``"rgb"``, ``(H, W)`` for ``"gray"``, the array's own
        channels for ``"any"``."""
        given, obj, key = self._given(path)
        if not given:
            return load_image(path, mode=mode)
        return image_from_array(obj, key, mode=mode)

    def face_labels(self, path: Path | str, n_faces: int | None = None) -> np.ndarray:
        """``(#F,) int32`` face labels from a ``labels.ply`` file or given as an integer array."""
        given, obj, key = self._given(path)
        if not given:
            return load_face_labels(path)
        labels = np.asarray(obj)
        if labels.ndim != 1 or not np.issubdtype(labels.dtype, np.integer):
            raise InputError(f"{key}: face labels must be a 1-D integer array, got {labels.dtype} {labels.shape}")
        if n_faces is not None and len(labels) != n_faces:
            raise InputError(f"{key}: {len(labels)} face labels for a mesh of {n_faces} faces")
        return labels.astype(np.int32)


def image_from_array(obj: object, key: str, *, mode: Literal["rgb", "gray", "any"] = "rgb") -> np.ndarray:
    """An image array given in memory, checked and converted like a file's pixels: ``uint8`` and
    ``uint16`` scaled to [0, 1], floats must be finite and are clipped to [0, 1]; in ``"rgb"`` and
    ``"gray"`` mode an alpha channel (2 or 4 channels) is composited over white."""
    if not isinstance(obj, np.ndarray):
        raise InputError(f"{key}: expected an image array, got {type(obj).__name__}")
    if obj.ndim not in (2, 3) or (obj.ndim == 3 and obj.shape[2] not in (1, 2, 3, 4)):
        raise InputError(f"{key}: an image is (H, W) or (H, W, 1-4), got shape {obj.shape}")
    if obj.size == 0:
        raise InputError(f"{key}: image is empty")
    if obj.dtype == np.uint8:
        img = obj.astype(np.float32) / 255.0
    elif obj.dtype == np.uint16:
        img = obj.astype(np.float32) / 65535.0
    elif np.issubdtype(obj.dtype, np.floating) or obj.dtype == bool:
        img = obj.astype(np.float32)
        if not np.isfinite(img).all():
            raise InputError(f"{key}: image has non-finite values")
        img = np.clip(img, 0.0, 1.0)
    else:
        raise InputError(f"{key}: image dtype {obj.dtype} is not uint8, uint16 or float")
    if mode == "any":
        return np.ascontiguousarray(img)
    if img.ndim == 3 and img.shape[2] in (2, 4):
        alpha = img[..., -1:]
        img = img[..., :-1] * alpha + (1.0 - alpha)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    if mode == "rgb":
        return np.ascontiguousarray(np.repeat(img[..., None], 3, axis=2) if img.ndim == 2 else img)
    if img.ndim == 3:
        img = img @ LUMINANCE
    return np.ascontiguousarray(img.astype(np.float32))
