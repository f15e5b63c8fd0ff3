"""USD output (issue 34, deliverable 5): written with usd-core, read back with pxr (same counts, UVs
as a multiset of corners, materials, textures) and checked by usd-core's validators (UsdValidation,
which replaced the Python ComplianceChecker that usdchecker ran before 25.x)."""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from synthkit.asset import Asset, Material
from synthkit.config import validate_config
from synthkit.errors import ConfigError
from synthkit.io import usd
from synthkit.io.assets import load_asset, save_asset
from synthkit.io.images import save_image
from synthkit.io.usd import UsdMaterial, load_usd, write_usd
from synthkit.methods.petri.config import PetriConfig

pxr = pytest.importorskip("pxr", reason="usd-core is not installed (pip install 'synthkit[usd]')")
from pxr import Usd, UsdGeom, UsdShade, UsdValidation  # noqa: E402

KENNEY = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "meshes" / "kenney-city"


def validation_issues(path: Path) -> list[str]:
    """Every error and warning of all usd-core validators on the stage at ``path``."""
    context = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    return [f"{e.GetType()}: {e.GetMessage()}" for e in context.Validate(Usd.Stage.Open(str(path)))]


def grid(n=3):
    """A unit square of ``2 n^2`` triangles, ``V (#V, 3)`` with one loose vertex appended, ``F (#F, 3)``."""
    xs = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(xs, xs)
    V = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    q = (np.arange(n * n) // n) * (n + 1) + np.arange(n * n) % n
    F = np.concatenate([np.c_[q, q + 1, q + n + 2], np.c_[q, q + n + 2, q + n + 1]])
    return np.vstack([V, [[5.0, 5.0, 5.0]]]), F


def two_material_asset():
    """The grid with UVs, corner colours, a textured material (an RGBA 8x6 image), a plain one with a
    name that is no USD identifier, and two faces without a material."""
    V, F = grid()
    uv = V[F][..., :2] * 0.5
    rng = np.random.default_rng(0)
    color = rng.integers(0, 256, (len(F), 3, 4)).astype(np.uint8)
    color[..., 3] = 255
    fm = np.where(np.arange(len(F)) % 2 == 0, 0, 1)
    fm[:2] = -1
    image = rng.integers(0, 256, (6, 8, 4)).astype(np.uint8)
    materials = [Material("bricks", color=np.array([1, 1, 1, 1.0]), image=image),
                 Material("red paint 2", color=np.array([0.8, 0.1, 0.1, 1.0]))]
    return Asset(V, F, uv, color, fm, materials, "my wall-1", Path("wall.obj"))


def corner_multiset(uv: np.ndarray) -> np.ndarray:
    return np.unique(np.round(np.asarray(uv, np.float64).reshape(-1, 2), 6), axis=0)


@pytest.mark.parametrize("suffix", [".usdc", ".usda"])
def test_written_stage_reads_back_with_pxr_and_passes_the_validators(tmp_path, suffix):
    a = two_material_asset()
    path = tmp_path / f"wall{suffix}"
    written = save_asset(path, a.V, a.F, like=a, corner_uv=a.corner_uv, face_material=a.face_material,
                             corner_color=a.corner_color)
    assert written == [path.name, "wall_bricks.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(written)  # no temporary file left
    assert validation_issues(path) == []
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == "Y" and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    root = stage.GetDefaultPrim()
    assert root.GetName() == "my_wall_1" and root.GetDisplayName() == "my wall-1"
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(root.GetPath().AppendChild("my_wall_1")))
    assert len(mesh.GetPointsAttr().Get()) == len(a.V) - 1  # the loose vertex is not written
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [3] * len(a.F)
    assert len(mesh.GetFaceVertexIndicesAttr().Get()) == 3 * len(a.F)
    assert mesh.GetNormalsInterpolation() == "faceVarying" and len(mesh.GetNormalsAttr().Get()) == 3 * len(a.F)
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == "faceVarying" and st.IsIndexed()
    np.testing.assert_allclose(corner_multiset(st.ComputeFlattened()), corner_multiset(a.corner_uv), atol=1e-6)
    subsets = UsdShade.MaterialBindingAPI(mesh.GetPrim()).GetMaterialBindSubsets()
    assert [s.GetFamilyNameAttr().Get() for s in subsets] == ["materialBind"] * 2
    bound = {s.GetPrim().GetName(): (UsdShade.MaterialBindingAPI(s.GetPrim()).ComputeBoundMaterial()[0],
                                     len(s.GetIndicesAttr().Get())) for s in subsets}
    assert {k: n for k, (_, n) in bound.items()} == {"bricks": 8, "red_paint_2": 8}
    assert bound["red_paint_2"][0].GetPrim().GetDisplayName() == "red paint 2"
    texture = UsdShade.Shader(stage.GetPrimAtPath(bound["bricks"][0].GetPath().AppendChild("DiffuseTexture")))
    file = texture.GetInput("file").Get()
    assert file.path == "./wall_bricks.png"
    with Image.open(tmp_path / "wall_bricks.png") as img:
        assert img.size == (8, 6) and img.mode == "RGBA"


def test_read_back_asset_equals_the_written_one(tmp_path):
    a = two_material_asset()
    save_asset(tmp_path / "w.usdc", a.V, a.F, like=a, corner_uv=a.corner_uv, face_material=a.face_material,
                   corner_color=a.corner_color)
    b = load_usd(tmp_path / "w.usdc")
    np.testing.assert_allclose(b.V[b.F], a.V[a.F], atol=1e-6)
    np.testing.assert_allclose(b.corner_uv, a.corner_uv, atol=1e-6)
    np.testing.assert_array_equal(b.corner_color, a.corner_color)
    assert [m.name for m in b.materials] == ["bricks", "red paint 2"]
    np.testing.assert_array_equal(b.face_material, a.face_material)
    np.testing.assert_array_equal(b.materials[0].image, a.materials[0].image)
    np.testing.assert_allclose(b.materials[1].color, [0.8, 0.1, 0.1, 1.0], atol=1e-6)


def test_one_material_is_bound_on_the_mesh_and_texture_bytes_are_kept(tmp_path):
    V, F = grid(2)
    save_image(tmp_path / "src.png", np.random.default_rng(1).random((5, 7, 3)))
    obj = tmp_path / "in.obj"
    (tmp_path / "in.mtl").write_text("newmtl skin\nKd 1 1 1\nmap_Kd src.png\n")
    lines = ["mtllib in.mtl", "usemtl skin"] + [f"v {x} {y} {z}" for x, y, z in V[:-1]]
    lines += [f"vt {x} {y}" for x, y, _ in V[:-1]] + [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}"
                                                      for a, b, c in F]
    obj.write_text("\n".join(lines) + "\n")
    a = load_asset(obj)
    out = tmp_path / "out"
    out.mkdir()
    written = save_asset(out / "m.usda", a.V, a.F, like=a, corner_uv=a.corner_uv, face_material=a.face_material)
    assert written == ["m.usda", "m_src.png"]
    assert (out / "m_src.png").read_bytes() == (tmp_path / "src.png").read_bytes()
    stage = Usd.Stage.Open(str(out / "m.usda"))
    mesh = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    assert UsdShade.MaterialBindingAPI(mesh).GetMaterialBindSubsets() == []
    assert UsdShade.MaterialBindingAPI(mesh).ComputeBoundMaterial()[0].GetPrim().GetName() == "skin"
    assert validation_issues(out / "m.usda") == []


def test_the_validators_do_find_problems(tmp_path):
    """The check is not vacuous: a stage without defaultPrim, upAxis and metersPerUnit fails it."""
    stage = Usd.Stage.CreateNew(str(tmp_path / "bare.usda"))
    UsdGeom.Mesh.Define(stage, "/m")
    stage.Save()
    assert len(validation_issues(tmp_path / "bare.usda")) >= 2


@pytest.mark.skipif(not (KENNEY / "building-small-a.glb").is_file(), reason="../shared/data absent")
def test_kenney_glb_keeps_faces_uvs_material_and_texture(tmp_path):
    a = load_asset(KENNEY / "building-small-a.glb")
    written = save_asset(tmp_path / "k.usdc", a.V, a.F, like=a, corner_uv=a.corner_uv,
                             face_material=a.face_material, corner_color=a.corner_color)
    assert written == ["k.usdc", "k_colormap.png"] and validation_issues(tmp_path / "k.usdc") == []
    b = load_usd(tmp_path / "k.usdc")
    assert len(b.F) == len(a.F) and [m.name for m in b.materials] == ["colormap"]
    np.testing.assert_allclose(corner_multiset(b.corner_uv), corner_multiset(a.corner_uv), atol=1e-6)
    assert b.materials[0].image.shape == a.materials[0].image.shape


def test_shapes_and_suffix_are_checked(tmp_path):
    V, F = grid(1)
    with pytest.raises(ValueError, match="unsupported USD format"):
        write_usd(tmp_path / "m.usdz", V, F)
    with pytest.raises(ValueError, match="corner_uv must have shape"):
        write_usd(tmp_path / "m.usdc", V, F, corner_uv=np.zeros((1, 3, 2)))
    with pytest.raises(ValueError, match="face_material indexes 1 materials"):
        write_usd(tmp_path / "m.usdc", V, F, face_material=np.array([0, 1]),
                  materials=[UsdMaterial("a", np.ones(4))])
    assert list(tmp_path.iterdir()) == []


def test_without_usd_core_one_line_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setattr(usd, "usd_installed", lambda: False)
    V, F = grid(1)
    with pytest.raises(ConfigError, match=r"pip install 'synthkit\[usd\]'"):
        write_usd(tmp_path / "m.usdc", V, F)
    (tmp_path / "ex.ply").write_bytes(b"")
    data = {"method": "petri-synth", "example": "ex.ply", "lattice": {"unit": [1, 1, 1]},
            "construction": {"plane": "xz", "points": [[0, 0], [1, 0]]},
            "output": {"mesh_format": "usd"}}
    with pytest.raises(ConfigError) as err:
        validate_config(PetriConfig, data, source="c.yaml", base_dir=tmp_path)
    assert "output.mesh_format" in str(err.value) and "pip install 'synthkit[usd]'" in str(err.value)
    assert "\n" not in str(err.value).strip()
