"""Shared fixtures: a tiny test-only method ('echo') and small input files."""

import importlib
import os
import pkgutil
import sys
from pathlib import Path

import numpy as np
import pytest

from synthkit.io.images import save_image
from synthkit.methods import METHODS

FAKES = Path(__file__).parent / "fakes"
REPO = Path(__file__).resolve().parent.parent
SHARED_DATA = REPO.parent / "shared" / "data"


@pytest.fixture
def echo_method(monkeypatch):
    """Register the test-only 'echo' method for the duration of a test."""
    monkeypatch.syspath_prepend(str(FAKES))
    monkeypatch.setitem(METHODS, "echo", "echo_method")
    return "echo"


@pytest.fixture
def echo_config(tmp_path, echo_method):
    """A valid echo config beside a 4x4 grey gradient image; returns the config path."""
    img = np.linspace(0.0, 1.0, 16, dtype=np.float32).reshape(4, 4)
    save_image(tmp_path / "in.png", img)
    cfg = tmp_path / "echo.yaml"
    cfg.write_text("method: echo\nimage: in.png\nmode: invert\n")
    return cfg


def _untracked_files() -> set[str] | None:
    """Files in the repository that git neither tracks nor ignores; None outside a git checkout."""
    import subprocess

    try:
        done = subprocess.run(["git", "ls-files", "--others", "--exclude-standard"], cwd=REPO,
                              capture_output=True, text=True, timeout=60, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return set(done.stdout.splitlines())


@pytest.fixture(scope="session", autouse=True)
def repository_left_clean():
    """No test may leave a file in the repository (a test once wrote a mesh named 'ply' into the
    current folder, and it was committed)."""
    before = _untracked_files()
    yield
    after = _untracked_files()
    if before is not None and after is not None:
        new = sorted(after - before)
        assert not new, f"tests left files in the repository: {new[:10]}"


WRITERS = ("write_bytes_atomic", "write_text_atomic")
"""synthkit's file writers (synthkit.io.atomic), under the names modules import them as."""


def _import_every_module() -> None:
    """Import all of synthkit, so that a module imported later cannot bind a patched writer."""
    import synthkit

    for info in pkgutil.walk_packages(synthkit.__path__, "synthkit."):
        try:
            importlib.import_module(info.name)
        except ImportError:  # an optional extra (dask) that is not installed
            pass


def _refuse_writes(monkeypatch: pytest.MonkeyPatch, folder: Path) -> None:
    """Work in ``folder`` with every synthkit writer, ``os.replace`` and ``np.save`` raising."""
    _import_every_module()
    monkeypatch.chdir(folder)

    def refuse(*args, **kwargs):
        raise AssertionError(f"an in-memory run wrote a file ({args[0] if args else ''})")

    for name, module in list(sys.modules.items()):
        if name == "synthkit" or name.startswith("synthkit."):
            for writer in WRITERS:
                if hasattr(module, writer):
                    monkeypatch.setattr(module, writer, refuse)
    real_replace = os.replace

    def replace_only_compiled_code(src, dst, *args, **kwargs):
        # numba saves a kernel compiled for the first time into __pycache__ (or its cache folder)
        # by os.replace: compiled code, not an output of the run
        if _compile_cache(dst):
            return real_replace(src, dst, *args, **kwargs)
        return refuse(src, dst)

    monkeypatch.setattr(os, "replace", replace_only_compiled_code)
    monkeypatch.setattr(np, "save", refuse)


def _compile_cache(path) -> bool:
    """Whether ``path`` lies in a ``__pycache__`` folder or numba's cache folder."""
    import numba

    path = Path(os.fspath(path)).resolve()
    cache_dir = getattr(numba.config, "CACHE_DIR", "") or ""
    return "__pycache__" in path.parts or (bool(cache_dir) and path.is_relative_to(Path(cache_dir).resolve()))


@pytest.fixture(scope="session")
def refuse_writes():
    """``refuse_writes(monkeypatch, folder)``: for fixtures of a wider scope than ``nothing_written``."""
    return _refuse_writes


@pytest.fixture
def nothing_written(tmp_path, monkeypatch):
    """An empty current folder in which nothing may be written, every synthkit writer raising for
    the test's duration; yields the folder and checks it is still empty."""
    folder = tmp_path / "cwd"
    folder.mkdir()
    _refuse_writes(monkeypatch, folder)
    yield folder
    assert os.listdir(folder) == []
