"""Dependencies with reasons: bounded requirements, and a constraints file that pins them all."""

import re
import tomllib
from pathlib import Path

import pytest

packaging = pytest.importorskip("packaging.requirements", reason="packaging (a dask dependency) is not installed")

REPO = Path(__file__).resolve().parent.parent
PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]


def _pins() -> dict[str, str]:
    pins = {}
    for line in (REPO / "constraints.txt").read_text().splitlines():
        line = line.split("#")[0].strip()
        if line:
            name, version = line.split("==")
            pins[re.sub(r"[-_.]+", "-", name).lower()] = version
    return pins


def _requirements(groups=("dev", "dist", "usd")):
    reqs = list(PROJECT["dependencies"])
    for group in groups:
        reqs += PROJECT["optional-dependencies"][group]
    return [packaging.Requirement(r) for r in reqs]


@pytest.mark.parametrize("req", _requirements(("dev", "dist", "usd", "bench")), ids=str)
def test_every_requirement_has_a_major_upper_bound(req):
    assert any(spec.operator == "<" for spec in req.specifier), f"{req} has no upper bound"


@pytest.mark.parametrize("req", _requirements(), ids=str)
def test_constraints_pin_every_requirement_within_its_bounds(req):
    pins = _pins()
    name = re.sub(r"[-_.]+", "-", req.name).lower()
    assert name in pins, f"{req.name} is not pinned in constraints.txt"
    assert req.specifier.contains(pins[name], prereleases=True), f"{req.name}=={pins[name]} is outside {req}"
