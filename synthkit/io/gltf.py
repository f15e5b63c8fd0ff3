"""glTF 2.0: what a file says beyond its geometry (:func:`read_gltf_info`), and the GLB writer
(:func:`glb_bytes`).

The geometry of a glTF input is read by trimesh (:mod:`synthkit.io.assets`); this module reads
the file's JSON for the names and objects trimesh does not carry through (scene, node and mesh
names, material, texture, sampler and image objects with their names, ``extensionsUsed``, which
attributes the primitives had), so a GLB written from it keeps them.

A written GLB holds one node with one mesh and one primitive per material. Its materials are
the input's JSON objects, with their textures, samplers and images (embedded; an image the
input referenced by URI is embedded with the same bytes); a material that came from elsewhere
(an OBJ, a mesh in memory) becomes a metallic-roughness material from its base colour and
texture. Every primitive has ``NORMAL`` (per corner, :func:`~synthkit.io.assets.corner_normals`),
``TEXCOORD_0`` where the faces have UVs, ``TANGENT`` where the input had tangents and
``COLOR_0`` for corner colours.
"""

from __future__ import annotations

import base64
import copy
import io
import json
import struct
from pathlib import Path

import numpy as np

from synthkit.asset import Asset, GltfInfo, Material
from synthkit.errors import InputError

__all__ = ["read_gltf_info", "glb_bytes"]

_GLB_MAGIC = 0x46546C67
_JSON_CHUNK = 0x4E4F534A
_BIN_CHUNK = 0x004E4942
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_FLOAT, _UNSIGNED_BYTE, _UNSIGNED_INT = 5126, 5121, 5125
_MIME = {b"\x89PNG": "image/png", b"\xff\xd8\xff": "image/jpeg"}


def _chunks(data: bytes) -> tuple[dict, bytes]:
    """The JSON and binary chunks of GLB bytes."""
    magic, _, length = struct.unpack_from("<III", data, 0)
    if magic != _GLB_MAGIC or length > len(data):
        raise ValueError("not a whole GLB file")
    at, doc, binary = 12, None, b""
    while at + 8 <= length:
        size, kind = struct.unpack_from("<II", data, at)
        chunk = data[at + 8:at + 8 + size]
        if kind == _JSON_CHUNK:
            doc = json.loads(chunk.decode("utf-8"))
        elif kind == _BIN_CHUNK:
            binary = chunk
        at += 8 + size
    if doc is None:
        raise ValueError("GLB has no JSON chunk")
    return doc, binary


def _uri_bytes(uri: str, folder: Path) -> bytes:
    if uri.startswith("data:"):
        return base64.b64decode(uri.split(",", 1)[1])
    from urllib.parse import unquote

    return (folder / unquote(uri)).read_bytes()


def _image_bytes(doc: dict, image: dict, binary: bytes, folder: Path) -> bytes:
    """The file bytes of ``image``: from its buffer view (the GLB's binary chunk, or a buffer's URI)
    or its own URI."""
    if "bufferView" in image:
        view = doc["bufferViews"][image["bufferView"]]
        buffer = doc["buffers"][view.get("buffer", 0)]
        data = binary if "uri" not in buffer else _uri_bytes(buffer["uri"], folder)
        start = view.get("byteOffset", 0)
        return data[start:start + view["byteLength"]]
    return _uri_bytes(image["uri"], folder)


def read_gltf_info(path: Path) -> GltfInfo:
    """The names and objects of the glTF file ``path`` (GLB or ``.gltf``) that a GLB written from
    it keeps (module docstring). An image that cannot be read keeps empty bytes (a material using
    it is written from its colour and decoded texture).
    Raises InputError naming the file when its JSON cannot be read."""
    try:
        data = path.read_bytes()
        doc, binary = _chunks(data) if data[:4] == b"glTF" else (json.loads(data.decode("utf-8")), b"")
    except (OSError, ValueError, UnicodeDecodeError, struct.error) as exc:
        raise InputError(f"{path}: cannot read glTF: {exc}") from None
    scenes = doc.get("scenes") or [{}]
    scene = scenes[doc.get("scene", 0)] if doc.get("scene", 0) < len(scenes) else {}
    nodes = doc.get("nodes", [])
    mesh_nodes = [n for n in nodes if "mesh" in n]
    node = mesh_nodes[0] if len(mesh_nodes) == 1 else {}
    meshes = doc.get("meshes", [])
    images = []
    for image in doc.get("images", []):
        kept = {k: v for k, v in image.items() if k not in ("uri", "bufferView")}
        try:
            images.append((kept, _image_bytes(doc, image, binary, path.parent)))
        except (OSError, ValueError, KeyError, IndexError):
            images.append((kept, b""))
    tangents = any("TANGENT" in p.get("attributes", {}) for m in meshes for p in m.get("primitives", []))
    return GltfInfo(scene=scene.get("name"), node=node.get("name"),
                    mesh=meshes[node["mesh"]].get("name") if "mesh" in node and node["mesh"] < len(meshes) else None,
                    materials=doc.get("materials", []), textures=doc.get("textures", []),
                    samplers=doc.get("samplers", []), images=images, tangents=tangents,
                    extensions_used=doc.get("extensionsUsed", []))


class _Builder:
    """The JSON document and binary buffer of a GLB being written."""

    def __init__(self) -> None:
        self.doc: dict = {"asset": {"version": "2.0", "generator": "synthkit"}, "accessors": [], "bufferViews": []}
        self.binary = bytearray()

    def view(self, data: bytes, target: int | None) -> int:
        self.binary += b"\0" * (-len(self.binary) % 4)
        entry = {"buffer": 0, "byteOffset": len(self.binary), "byteLength": len(data)}
        if target is not None:
            entry["target"] = target
        self.binary += data
        self.doc["bufferViews"].append(entry)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, array: np.ndarray, kind: str, *, target: int = _ARRAY_BUFFER, bounds: bool = False,
                 normalized: bool = False) -> int:
        component = {np.float32: _FLOAT, np.uint8: _UNSIGNED_BYTE, np.uint32: _UNSIGNED_INT}[array.dtype.type]
        entry = {"bufferView": self.view(np.ascontiguousarray(array).tobytes(), target), "componentType": component,
                 "count": int(len(array) if kind != "SCALAR" else array.size), "type": kind}
        if normalized:
            entry["normalized"] = True
        if bounds:
            entry["min"] = array.min(axis=0).tolist()
            entry["max"] = array.max(axis=0).tolist()
        self.doc["accessors"].append(entry)
        return len(self.doc["accessors"]) - 1

    def add(self, key: str, entry: dict) -> int:
        self.doc.setdefault(key, []).append(entry)
        return len(self.doc[key]) - 1

    def bytes(self) -> bytes:
        self.binary += b"\0" * (-len(self.binary) % 4)
        self.doc["buffers"] = [{"byteLength": len(self.binary)}]
        text = json.dumps(self.doc, separators=(",", ":")).encode("utf-8")
        text += b" " * (-len(text) % 4)
        total = 12 + 8 + len(text) + 8 + len(self.binary)
        return b"".join([struct.pack("<III", _GLB_MAGIC, 2, total), struct.pack("<II", len(text), _JSON_CHUNK), text,
                         struct.pack("<II", len(self.binary), _BIN_CHUNK), bytes(self.binary)])


class _Materials:
    """The materials written into a GLB, each once, with the textures, samplers and images they use."""

    def __init__(self, builder: _Builder, like: Asset) -> None:
        self.b, self.like = builder, like
        self.done: dict[int, int] = {}
        self.textures: dict[int, int] = {}
        self.samplers: dict[int, int] = {}
        self.images: dict[int, int] = {}

    def index(self, k: int) -> int:
        """The written index of material ``k`` of ``like``."""
        if k not in self.done:
            mat = self.like.materials[k]
            gltf = self.like.gltf
            if gltf is not None and mat.gltf_index is not None and self._readable(gltf.materials[mat.gltf_index]):
                entry = self._remap(copy.deepcopy(gltf.materials[mat.gltf_index]))
            else:
                entry = self._from_material(mat)
            self.done[k] = self.b.add("materials", entry)
        return self.done[k]

    def _readable(self, node) -> bool:
        """Whether every texture a material's JSON ``node`` references has an image whose bytes were
        read (else the material is written from its colour and decoded texture)."""
        gltf = self.like.gltf
        if isinstance(node, dict):
            for key, value in node.items():
                if key.endswith("Texture") and isinstance(value, dict) and "index" in value:
                    t = value["index"]
                    source = gltf.textures[t].get("source") if t < len(gltf.textures) else None
                    if source is None or source >= len(gltf.images) or not gltf.images[source][1]:
                        return False
                elif not self._readable(value):
                    return False
        elif isinstance(node, list):
            return all(self._readable(v) for v in node)
        return True

    def _remap(self, node):
        """``node`` (a material's JSON) with every texture reference's index renumbered."""
        if isinstance(node, dict):
            for key, value in node.items():
                if key.endswith("Texture") and isinstance(value, dict) and "index" in value:
                    value["index"] = self._texture(value["index"])
                node[key] = self._remap(value)
        elif isinstance(node, list):
            node = [self._remap(v) for v in node]
        return node

    def _texture(self, t: int) -> int:
        if t not in self.textures:
            entry = dict(self.like.gltf.textures[t])
            if "sampler" in entry:
                s = entry["sampler"]
                if s not in self.samplers:
                    self.samplers[s] = self.b.add("samplers", dict(self.like.gltf.samplers[s]))
                entry["sampler"] = self.samplers[s]
            if "source" in entry:
                entry["source"] = self._image(entry["source"])
            self.textures[t] = self.b.add("textures", entry)
        return self.textures[t]

    def _image(self, i: int) -> int:
        if i not in self.images:
            kept, data = self.like.gltf.images[i]
            self.images[i] = self._image_entry(dict(kept), data)
        return self.images[i]

    def _image_entry(self, entry: dict, data: bytes) -> int:
        entry["bufferView"] = self.b.view(data, None)
        entry.setdefault("mimeType", next((m for head, m in _MIME.items() if data.startswith(head)), "image/png"))
        return self.b.add("images", entry)

    def _from_material(self, mat: Material) -> dict:
        pbr = {"baseColorFactor": [float(c) for c in mat.color], "metallicFactor": 0.0, "roughnessFactor": 1.0}
        if mat.image is not None:
            image = self._image_entry({"name": mat.name}, _image_file_bytes(mat))
            sampler = self.b.add("samplers", {"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497})
            pbr["baseColorTexture"] = {"index": self.b.add("textures", {"sampler": sampler, "source": image})}
        return {"name": mat.name, "pbrMetallicRoughness": pbr}


def _image_file_bytes(mat: Material) -> bytes:
    """A PNG or JPEG file's bytes of ``mat``'s base-colour texture: its source file when that is one."""
    if mat.image_path is not None and mat.image_path.is_file():
        data = mat.image_path.read_bytes()
        if any(data.startswith(head) for head in _MIME):
            return data
    from PIL import Image

    out = io.BytesIO()
    Image.fromarray(mat.image).save(out, format="PNG")
    return out.getvalue()


def glb_bytes(V, F, corner_uv, face_material, corner_color, like: Asset, corner_normal, corner_tangent) -> bytes:
    """The GLB file of ``V (#V, 3)``, ``F (#F, 3)`` with ``corner_uv (#F, 3, 2)`` (or None),
    ``face_material (#F,)`` (indices into ``like.materials``, -1 none), ``corner_color (#F, 3, 4)
    uint8`` (or None), ``corner_normal (#F, 3, 3)`` and ``corner_tangent (#F, 3, 4)`` (or None),
    named and with materials as ``like`` (module docstring)."""
    b = _Builder()
    materials = _Materials(b, like)
    primitives = []
    for k in np.unique(face_material):
        faces = np.flatnonzero(face_material == k)
        primitives.append(_primitive(b, V, F[faces], None if corner_uv is None or k < 0 else corner_uv[faces],
                                     None if corner_color is None else corner_color[faces], corner_normal[faces],
                                     None if corner_tangent is None or k < 0 else corner_tangent[faces]))
        if k >= 0:
            primitives[-1]["material"] = materials.index(int(k))
    info = like.gltf or GltfInfo()
    b.add("meshes", {"name": info.mesh or like.name, "primitives": primitives})
    b.add("nodes", {"name": info.node or like.name, "mesh": 0})
    b.doc["scenes"] = [{"name": info.scene or like.name, "nodes": [0]}]
    b.doc["scene"] = 0
    used = sorted(e for e in info.extensions_used if e in json.dumps(b.doc.get("materials", [])))
    if used:
        b.doc["extensionsUsed"] = used
    return b.bytes()


def _primitive(b: _Builder, V, F, uv, color, normal, tangent) -> dict:
    """One primitive over the distinct (position, UV, colour, normal, tangent) corners of ``F``."""
    columns = [F.reshape(-1, 1).astype(np.float64), normal.reshape(-1, 3)]
    if uv is not None:
        columns.append(np.nan_to_num(uv.reshape(-1, 2), nan=0.0))
    if color is not None:
        columns.append(color.reshape(-1, 4).astype(np.float64))
    if tangent is not None:
        columns.append(tangent.reshape(-1, 4))
    table, inverse = np.unique(np.concatenate(columns, axis=1), axis=0, return_inverse=True)
    attributes = {"POSITION": b.accessor(V[table[:, 0].astype(np.int64)].astype(np.float32), "VEC3", bounds=True),
                  "NORMAL": b.accessor(table[:, 1:4].astype(np.float32), "VEC3")}
    at = 4
    if uv is not None:
        st = table[:, at:at + 2].copy()
        st[:, 1] = 1.0 - st[:, 1]  # glTF's texture origin is the top left
        attributes["TEXCOORD_0"] = b.accessor(st.astype(np.float32), "VEC2")
        at += 2
    if color is not None:
        attributes["COLOR_0"] = b.accessor(table[:, at:at + 4].astype(np.uint8), "VEC4", normalized=True)
        at += 4
    if tangent is not None:
        attributes["TANGENT"] = b.accessor(table[:, at:at + 4].astype(np.float32), "VEC4")
    indices = b.accessor(inverse.reshape(-1).astype(np.uint32), "SCALAR", target=_ELEMENT_ARRAY_BUFFER)
    return {"attributes": attributes, "indices": indices, "mode": 4}
