"""Every bundled config validates against its method's schema, and its files exist."""

from pathlib import Path

import pytest

from synthkit.methods import available_methods
from synthkit.runner import load_method_config

REPO = Path(__file__).resolve().parents[1]

CONFIGS = sorted((REPO / "configs").glob("*/*.yaml"))


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_bundled_config_validates(path):
    method, cfg, inputs = load_method_config(path)
    assert method == path.parent.name
    assert cfg.method == method
    assert all(p.is_file() for p in inputs)


def test_every_available_method_has_a_config():
    folders = {p.parent.name for p in CONFIGS}
    assert set(available_methods()) <= folders
