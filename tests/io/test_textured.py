"""OBJ companions found where studios keep them, copied inside the output folder only."""

import numpy as np
import pytest

from synthkit.errors import InputError
from synthkit.io.textured import companion_files, load_textured, material_textures, save_textured

from .test_assets import QUAD_OBJ, _texture, _tree


def _studio_layout(tmp_path, map_kd="../textures/bricks wall.png", mtllib="../materials/wall.mtl"):
    """models/wall.obj, materials/wall.mtl and textures/bricks wall.png, as many studios lay them out."""
    for folder in ("models", "materials", "textures"):
        (tmp_path / folder).mkdir()
    _texture(tmp_path / "textures" / "bricks wall.png")
    (tmp_path / "materials" / "wall.mtl").write_text(f"newmtl bricks\nKd 1 1 1\nmap_Kd {map_kd}\n")
    obj = tmp_path / "models" / "wall.obj"
    obj.write_text(QUAD_OBJ.format(mtl=mtllib))
    return obj


def test_sibling_folders_are_read_and_copied_under_safe_names(tmp_path):
    mesh = load_textured(_studio_layout(tmp_path))
    assert companion_files(mesh) == ["wall.mtl", "bricks_wall.png"]
    assert material_textures(mesh) == {"bricks": tmp_path / "textures" / "bricks wall.png"}
    out = tmp_path / "out"
    out.mkdir()
    before = _tree(tmp_path)
    save_textured(mesh, mesh.positions + 1.0, out / "wall.obj")
    assert sorted(set(_tree(tmp_path)) - set(before)) == ["out/bricks_wall.png", "out/wall.mtl", "out/wall.obj"]
    assert "mtllib wall.mtl" in (out / "wall.obj").read_text()
    assert (out / "wall.mtl").read_text().splitlines()[-1] == "map_Kd bricks_wall.png"
    again = load_textured(out / "wall.obj")
    assert np.allclose(again.positions, mesh.positions + 1.0)
    assert (out / "bricks_wall.png").read_bytes() == (tmp_path / "textures" / "bricks wall.png").read_bytes()


def test_absolute_texture_path(tmp_path):
    obj = _studio_layout(tmp_path, map_kd=str(tmp_path / "textures" / "bricks wall.png"))
    assert companion_files(load_textured(obj)) == ["wall.mtl", "bricks_wall.png"]


def test_a_texture_that_is_not_an_image_is_refused(tmp_path):
    (tmp_path / "secret").write_text("root:x:0:0:root:/root:/bin/bash\n")
    obj = _studio_layout(tmp_path, map_kd=str(tmp_path / "secret"))
    with pytest.raises(InputError, match=r"wall.mtl: texture .*secret is not an image file"):
        companion_files(load_textured(obj))


def test_missing_texture_is_one_warning(tmp_path, caplog):
    obj = _studio_layout(tmp_path, map_kd="../textures/gone.png")
    with caplog.at_level("WARNING", logger="synthkit"):
        mesh = load_textured(obj)
    assert [r.getMessage() for r in caplog.records] == [
        f"{tmp_path / 'materials' / 'wall.mtl'}: texture file ../textures/gone.png is missing; written without it"]
    assert companion_files(mesh) == ["wall.mtl"]


def test_a_material_no_face_uses_any_more_is_not_copied(tmp_path):
    from synthkit.io.assets import load_asset
    from synthkit.io.textured import Retexture

    mesh = load_textured(_studio_layout(tmp_path))
    uv = np.nan_to_num(mesh.UV)
    entry = Retexture(faces=np.arange(len(mesh.F)), UV=uv, material="bricks_atlas", image_name="atlas.png",
                      image=np.full((4, 4, 3), 0.5, np.float32))
    assert companion_files(mesh, [entry]) == []
    out = tmp_path / "out"
    out.mkdir()
    save_textured(mesh, mesh.positions, out / "wall.obj", retexture=[entry])
    assert sorted(p.name for p in out.iterdir()) == ["atlas.png", "wall.obj", "wall.retex.mtl"]
    assert [line for line in (out / "wall.obj").read_text().splitlines() if line.startswith("mtllib")] == [
        "mtllib wall.retex.mtl"]
    written = load_asset(out / "wall.obj")
    assert [m.name for m in written.materials] == ["bricks_atlas"] and written.materials[0].image is not None
    half = Retexture(faces=np.arange(1), UV=uv, material="bricks_atlas", image_name="atlas.png",
                     image=np.full((4, 4, 3), 0.5, np.float32))
    assert companion_files(mesh, [half]) == ["wall.mtl", "bricks_wall.png"]
