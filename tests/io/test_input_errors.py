"""Bad input files give one line in synthkit's words: corrupt images (decoder warnings captured from
fd 2), permission denied, meshes naming missing textures, and the RGBA compositing rule."""

import hashlib
import logging
import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from synthkit.errors import InputError
from synthkit.io.images import load_image, save_image
from synthkit.io.meshes import load_mesh

TEXTURES = Path(__file__).resolve().parents[2] / "data-samples" / "textures"
CLI = [sys.executable, "-c", "from synthkit.cli.main import main; main()"]


def _snapshot(folder: Path) -> dict[str, str]:
    """Relative path -> SHA-256 of every file under ``folder`` (folders as "dir")."""
    return {p.relative_to(folder).as_posix(): "dir" if p.is_dir() else hashlib.sha256(p.read_bytes()).hexdigest()
            for p in folder.rglob("*")}


def _jpeg(tmp_path, name="ok.jpg"):
    path = tmp_path / name
    rgb = cv2.imread(str(TEXTURES / "wavy.png"))
    assert cv2.imwrite(str(path), rgb)
    return path


def _truncated_jpeg(tmp_path, name="trunc.jpg"):
    data = _jpeg(tmp_path).read_bytes()
    path = tmp_path / name
    path.write_bytes(data[: len(data) // 2])
    return path


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def _png_with_chunk(tmp_path, kind: bytes, body: bytes, name: str) -> Path:
    """A 4x4 RGB PNG with an extra chunk right after IHDR."""
    plain = tmp_path / ("plain_" + name)
    save_image(plain, np.full((4, 4, 3), 0.5, np.float32))
    data = plain.read_bytes()
    path = tmp_path / name
    path.write_bytes(data[:33] + _png_chunk(kind, body) + data[33:])
    return path


# -- decoder messages ------------------------------------------------------------------------------


def test_truncated_jpeg_is_corrupt_and_silent(tmp_path, capfd):
    path = _truncated_jpeg(tmp_path)
    with pytest.raises(InputError) as err:
        load_image(path)
    assert str(err.value) == f"{path}: corrupt image: Premature end of JPEG file"
    assert err.value.exit_code == 3
    assert capfd.readouterr() == ("", "")


def test_corrupt_jpeg_data_is_corrupt(tmp_path, capfd):
    data = bytearray(_jpeg(tmp_path).read_bytes())
    middle = len(data) // 2
    data[middle : middle + 64] = b"\xff" * 64
    path = tmp_path / "corrupt.jpg"
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"^.*corrupt\.jpg: corrupt image: Corrupt JPEG data: "):
        load_image(path)
    assert capfd.readouterr() == ("", "")


def test_broken_png_data_is_corrupt(tmp_path, capfd):
    save_image(tmp_path / "ok.png", cv2.imread(str(TEXTURES / "wavy.png"))[..., ::-1] / 255.0)
    data = bytearray((tmp_path / "ok.png").read_bytes())
    at = data.index(b"IDAT") + 6
    data[at] ^= 0xFF
    path = tmp_path / "broken.png"
    path.write_bytes(bytes(data))
    with pytest.raises(InputError) as err:
        load_image(path)
    assert str(err.value).startswith(f"{path}: corrupt image: ")
    assert "libpng" not in str(err.value) and "\n" not in str(err.value)
    assert capfd.readouterr() == ("", "")


def test_png_profile_warning_is_ignored(tmp_path, capfd):
    path = _png_with_chunk(tmp_path, b"iCCP", b"bogus\x00\x00" + zlib.compress(bytes(200)), "iccp.png")
    img = load_image(path)
    np.testing.assert_array_equal(img, np.full((4, 4, 3), 128 / 255, np.float32))
    assert capfd.readouterr() == ("", "")


def test_tiff_unknown_tag_is_ignored_truncated_tiff_is_corrupt(tmp_path, capfd):
    tifffile = pytest.importorskip("tifffile")
    rgb = np.full((8, 8, 3), 200, np.uint8)
    tagged = tmp_path / "tag.tif"
    tifffile.imwrite(tagged, rgb, extratags=[(65000, "s", 0, "hello", True)])
    np.testing.assert_array_equal(load_image(tagged), np.full((8, 8, 3), 200 / 255, np.float32))
    data = tagged.read_bytes()
    truncated = tmp_path / "trunc.tif"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"trunc\.tif: corrupt image: TIFF"):
        load_image(truncated)
    assert capfd.readouterr() == ("", "")


def test_save_image_is_silent(tmp_path, capfd):
    save_image(tmp_path / "a.jpg", np.full((4, 4), 0.25, np.float32))
    with pytest.raises(OSError, match="cannot write image"):
        save_image(tmp_path / "no-such-folder" / "a.png", np.zeros((4, 4), np.float32))
    assert capfd.readouterr() == ("", "")
    assert not list((tmp_path).glob("*.tmp*"))


def _quilt_config(tmp_path, source: Path) -> Path:
    cfg = tmp_path / "quilt.yaml"
    cfg.write_text(
        f"method: symmetry-texture\nmode: quilt\nsource: {source.name}\noutput_size: [32, 32]\n"
        "synth:\n  patch: 16\n  overlap: 6\n"
    )
    return cfg


def test_cli_truncated_jpeg_one_line_exit_3(tmp_path):
    """Through the real process: libjpeg's own line never reaches the terminal, ours does."""
    source = _truncated_jpeg(tmp_path, "wavy.jpg")
    cfg = _quilt_config(tmp_path, source)
    before = _snapshot(tmp_path)
    proc = subprocess.run([*CLI, "symmetry-texture", str(cfg), "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert proc.returncode == 3
    assert proc.stderr == f"error: {cfg}: {source}: corrupt image: Premature end of JPEG file\n"
    assert proc.stdout == ""
    assert _snapshot(tmp_path) == before


# -- permission denied -----------------------------------------------------------------------------


def _without_dac_override(cmd: list[str]) -> list[str]:
    """``cmd`` run so that file modes bind: as is for a normal user; for root, with the
    DAC-override capabilities dropped (setpriv), or skip when that is impossible."""
    if os.geteuid() != 0:
        return cmd
    setpriv = shutil.which("setpriv")
    wrapped = [setpriv, "--bounding-set=-dac_override,-dac_read_search"] if setpriv else None
    if wrapped is None or subprocess.run([*wrapped, "true"], capture_output=True).returncode != 0:
        pytest.skip("running as root and cannot drop CAP_DAC_OVERRIDE")
    return [*wrapped, *cmd]


def test_cli_unreadable_image_says_permission_denied(tmp_path):
    source = tmp_path / "wavy.png"
    shutil.copy(TEXTURES / "wavy.png", source)
    cfg = _quilt_config(tmp_path, source)
    before = _snapshot(tmp_path)
    source.chmod(0)
    proc = subprocess.run(_without_dac_override([*CLI, "symmetry-texture", str(cfg), "--out", str(tmp_path / "o")]),
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert proc.returncode == 3
    assert proc.stderr == f"error: {cfg}: {source}: permission denied (cannot read image)\n"
    source.chmod(0o644)
    assert _snapshot(tmp_path) == before


def test_cli_unreadable_mesh_says_permission_denied(tmp_path):
    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    cfg = tmp_path / "r.yaml"
    cfg.write_text("method: retarget\ninput: m.obj\nseed: 0\nanalyze_only: true\n")
    before = _snapshot(tmp_path)
    mesh.chmod(0)
    proc = subprocess.run(_without_dac_override([*CLI, "retarget", str(cfg), "--out", str(tmp_path / "o")]),
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert proc.returncode == 3
    assert proc.stderr == f"error: {cfg}: {mesh}: permission denied (cannot read mesh)\n"
    mesh.chmod(0o644)
    assert _snapshot(tmp_path) == before


def test_folder_and_empty_file_are_named(tmp_path):
    (tmp_path / "d.png").mkdir()
    with pytest.raises(InputError, match=r"d\.png: is a folder, not an image file$"):
        load_image(tmp_path / "d.png")
    (tmp_path / "d.obj").mkdir()
    with pytest.raises(InputError, match=r"d\.obj: is a folder, not a mesh file$"):
        load_mesh(tmp_path / "d.obj")
    (tmp_path / "e.png").write_bytes(b"")
    with pytest.raises(InputError, match=r"e\.png: image file is empty \(0 bytes\)$"):
        load_image(tmp_path / "e.png")


# -- meshes naming missing files -------------------------------------------------------------------

_TETRA_V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
_TETRA_F = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def _textured_ply(tmp_path) -> Path:
    header = (
        "ply\nformat ascii 1.0\ncomment TextureFile x.png\nelement vertex 4\nproperty float x\n"
        "property float y\nproperty float z\nproperty float s\nproperty float t\nelement face 4\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    body = "".join(f"{x} {y} {z} 0.5 0.5\n" for x, y, z in _TETRA_V)
    body += "".join(f"3 {a} {b} {c}\n" for a, b, c in _TETRA_F)
    path = tmp_path / "tex.ply"
    path.write_text(header + body)
    return path


def _obj(tmp_path, name: str, mtllib: str) -> Path:
    path = tmp_path / name
    path.write_text(
        f"mtllib {mtllib}\nusemtl mat\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in _TETRA_V)
        + "vt 0 0\nvt 1 0\nvt 0 1\nf 1/1 3/3 2/2\nf 1/1 2/2 4/3\n"
    )
    return path


def _mesh_warnings(caplog):
    assert not [r for r in caplog.records if r.name.startswith("trimesh")]
    return [(r.name, r.levelno, r.getMessage()) for r in caplog.records if r.levelno >= logging.WARNING]


def test_ply_missing_texture_one_warning(tmp_path, caplog, capfd):
    path = _textured_ply(tmp_path)
    caplog.set_level(logging.DEBUG)
    mesh = load_mesh(path)
    assert len(mesh.faces) == 4
    assert _mesh_warnings(caplog) == [
        ("synthkit.io.meshes", logging.WARNING,
         f"{path}: texture file x.png named by the mesh is missing; loading without texture")
    ]
    assert capfd.readouterr() == ("", "")


def test_obj_missing_material_and_texture_one_warning_each(tmp_path, caplog, capfd):
    caplog.set_level(logging.DEBUG)
    no_mtl = _obj(tmp_path, "nomtl.obj", "missing.mtl")
    load_mesh(no_mtl)
    (tmp_path / "mat.mtl").write_text("newmtl mat\nKd 1 1 1\nmap_Kd gone.png\n")
    no_tex = _obj(tmp_path, "notex.obj", "mat.mtl")
    load_mesh(no_tex)
    assert _mesh_warnings(caplog) == [
        ("synthkit.io.meshes", logging.WARNING,
         f"{no_mtl}: material file missing.mtl named by the mesh is missing; loading without materials"),
        ("synthkit.io.meshes", logging.WARNING,
         f"{no_tex}: texture file gone.png named by the mesh is missing; loading without texture"),
    ]
    assert capfd.readouterr() == ("", "")


def test_missing_texture_on_the_terminal_is_one_line(tmp_path):
    """With the CLI's logging set up, stderr holds our warning and nothing of trimesh's."""
    path = _textured_ply(tmp_path)
    code = ("from synthkit.cli.options import configure_logging; configure_logging(0); "
            f"from synthkit.io.meshes import load_mesh; load_mesh({str(path)!r})")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0
    assert proc.stderr == (
        f"WARNING synthkit.io.meshes: {path}: texture file x.png named by the mesh is missing; "
        "loading without texture\n"
    )


# -- transparency ----------------------------------------------------------------------------------


def _rgba_png(tmp_path, pixels) -> Path:
    """A 1xN straight-alpha RGBA PNG of 8-bit ``pixels`` [(r, g, b, a), ...]."""
    arr = np.array([pixels], dtype=np.uint8)
    path = tmp_path / "rgba.png"
    assert cv2.imwrite(str(path), arr[..., [2, 1, 0, 3]])
    return path


def test_rgba_is_composited_over_white(tmp_path, caplog):
    path = _rgba_png(tmp_path, [(255, 0, 0, 255), (0, 0, 0, 0), (0, 0, 255, 51), (10, 20, 30, 255)])
    caplog.set_level(logging.WARNING)
    rgb = load_image(path, mode="rgb")
    a = np.float32(51 / 255)
    expected = np.array([[
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 1.0],
        [1.0 - a, 1.0 - a, a + (1.0 - a)],
        [10 / 255, 20 / 255, 30 / 255],
    ]], dtype=np.float32)
    np.testing.assert_allclose(rgb, expected, rtol=0, atol=1e-7)
    gray = load_image(path, mode="gray")
    np.testing.assert_allclose(gray, expected @ np.array([0.299, 0.587, 0.114], np.float32), rtol=0, atol=1e-6)
    assert gray[0, 1] == pytest.approx(1.0, abs=1e-6)
    anyc = load_image(path, mode="any")
    np.testing.assert_array_equal(anyc[0, 1], [0.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(anyc[0, 2], np.array([0, 0, 255, 51], np.float32) / 255)
    assert [r.getMessage() for r in caplog.records] == [
        f"{path}: 2 of 4 pixels are transparent or translucent; composited over white (synthkit uses colour only)"
    ] * 2


def test_opaque_rgba_is_unchanged_and_quiet(tmp_path, caplog):
    path = _rgba_png(tmp_path, [(255, 0, 0, 255), (1, 2, 3, 255)])
    caplog.set_level(logging.WARNING)
    np.testing.assert_array_equal(load_image(path), np.array([[[1, 0, 0], [1 / 255, 2 / 255, 3 / 255]]], np.float32))
    assert caplog.records == []


def test_rgba_16bit_is_composited_over_white(tmp_path):
    arr = np.array([[[0, 0, 0, 0], [65535, 0, 0, 32768]]], dtype=np.uint16)  # BGRA for cv2
    path = tmp_path / "rgba16.png"
    assert cv2.imwrite(str(path), arr)
    a = np.float32(32768 / 65535)
    np.testing.assert_allclose(load_image(path), [[[1, 1, 1], [1 - a, 1 - a, a + (1 - a)]]], rtol=0, atol=1e-7)


# -- the capture itself ----------------------------------------------------------------------------


def test_capture_restores_fd2_and_opencv_log_level(tmp_path, capfd):
    from synthkit.io._capture import captured_stderr

    level = cv2.utils.logging.getLogLevel()
    with pytest.raises(RuntimeError), captured_stderr() as lines:
        os.write(2, b"from C\n\nsecond line  \n")
        raise RuntimeError("boom")
    assert lines == ["from C", "second line"]
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "after\n"
    with pytest.raises(InputError):
        load_image(_truncated_jpeg(tmp_path))
    assert cv2.utils.logging.getLogLevel() == level


def test_grey_alpha_is_composited_over_white(tmp_path):
    from synthkit.io.images import _over_white

    la = np.array([[[0.2, 0.5], [0.2, 1.0], [0.9, 0.0]]], dtype=np.float32)
    np.testing.assert_allclose(_over_white(la, tmp_path / "la.tif"), [[0.6, 0.2, 1.0]], rtol=0, atol=1e-7)
