"""What Blender sees of mesh files: run under ``.venv-blender/bin/python`` (bpy 5.0.1), never
imported by the test suite.

    python blender_probe.py OUT.json FILE...

One Blender for all files, reset to an empty scene before each. Per file, into ``OUT.json``: the
importer's output lines (captured at the file-descriptor level: Blender's C code prints its
warnings there), mesh objects' names, polygon and triangle counts, material names and the
images their texture nodes load (name, size, whether pixels loaded), UV layer counts, the
distinct (position, UV) corners (positions in the file's own axes), and the open
and non-manifold edges after welding by position within 1e-6 of the bounding-box diagonal.
"""

import json
import os
import sys
import tempfile

import bpy
import numpy as np


def _import(path: str) -> None:
    suffix = os.path.splitext(path)[1].lower()
    if suffix == ".obj":
        bpy.ops.wm.obj_import(filepath=path, forward_axis="Y", up_axis="Z")
    elif suffix in (".glb", ".gltf"):
        bpy.ops.import_scene.gltf(filepath=path)
    elif suffix == ".ply":
        bpy.ops.wm.ply_import(filepath=path, forward_axis="Y", up_axis="Z")
    else:
        bpy.ops.wm.usd_import(filepath=path)


def _captured(path: str) -> list[str]:
    """Import ``path``; the lines Blender printed meanwhile."""
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        sys.stdout.flush()
        saved = os.dup(1), os.dup(2)
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            _import(path)
        finally:
            sys.stdout.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
        tmp.seek(0)
        return [line for line in tmp.read().decode("utf-8", "replace").splitlines() if line.strip()]


def _file_axes(P: np.ndarray, suffix: str) -> np.ndarray:
    """Blender's Z-up positions back in the file's axes (glTF and USD files here are Y-up)."""
    if suffix in (".glb", ".gltf", ".usdc", ".usda"):
        return np.stack([P[:, 0], P[:, 2], -P[:, 1]], axis=1)
    return P


def _corners(objects, suffix: str) -> list:
    rows = []
    for obj in objects:
        mesh = obj.data
        P = np.array([obj.matrix_world @ v.co for v in mesh.vertices]).reshape(-1, 3)
        loop_vertex = np.array([loop.vertex_index for loop in mesh.loops], np.int64)
        pos = _file_axes(P, suffix)[loop_vertex]
        uv = np.array([d.uv[:] for d in mesh.uv_layers[0].data]) if mesh.uv_layers else np.zeros((len(pos), 2))
        rows.append(np.concatenate([pos, uv], axis=1))
    return np.unique(np.concatenate(rows) if rows else np.zeros((0, 5)), axis=0).tolist()


def _edges(objects) -> dict:
    import bmesh  # after bpy: bpy makes it importable

    bm = bmesh.new()
    for obj in objects:
        part = bmesh.new()
        part.from_mesh(obj.data)
        part.transform(obj.matrix_world)
        mesh = bpy.data.meshes.new("probe")
        part.to_mesh(mesh)
        bm.from_mesh(mesh)
        part.free()
    if not bm.verts:
        return {"open_edges": 0, "nonmanifold_edges": 0}
    P = np.array([v.co[:] for v in bm.verts])
    diagonal = float(np.linalg.norm(P.max(axis=0) - P.min(axis=0)))
    bmesh.ops.remove_doubles(bm, verts=bm.verts, dist=1e-6 * diagonal)
    faces = [len(e.link_faces) for e in bm.edges]
    bm.free()
    return {"open_edges": sum(n == 1 for n in faces), "nonmanifold_edges": sum(n > 2 for n in faces)}


def _materials(objects) -> list:
    found = {}
    for obj in objects:
        for slot in obj.material_slots:
            mat = slot.material
            if mat is None or mat.name in found:
                continue
            images = []
            if mat.node_tree is not None:
                for node in mat.node_tree.nodes:
                    if node.type == "TEX_IMAGE" and node.image is not None:
                        images.append({"name": node.image.name, "size": list(node.image.size),
                                       "loaded": bool(node.image.has_data)})
            found[mat.name] = images
    return [{"name": name, "images": images} for name, images in found.items()]


def probe(path: str) -> dict:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    lines = _captured(path)
    objects = [o for o in bpy.data.objects if o.type == "MESH"]
    for obj in objects:
        obj.data.calc_loop_triangles()
    return {
        "lines": lines,
        "objects": [o.name for o in objects],
        "polygons": sum(len(o.data.polygons) for o in objects),
        "triangles": sum(len(o.data.loop_triangles) for o in objects),
        "uv_layers": [len(o.data.uv_layers) for o in objects],
        "color_attributes": sum(len(o.data.color_attributes) for o in objects),
        "materials": _materials(objects),
        "corners": _corners(objects, os.path.splitext(path)[1].lower()),
        **_edges(objects),
    }


def main() -> None:
    out, files = sys.argv[1], sys.argv[2:]
    with open(out, "w") as f:
        json.dump({path: probe(path) for path in files}, f)


if __name__ == "__main__":
    main()
