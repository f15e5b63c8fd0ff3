"""Shared fixtures: a tiny test-only method ('echo') and small input files."""

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
