"""The wheel is the tool: build it, install it (not editable) into a fresh venv, and run it there.

The fresh venv (``python -m venv --without-pip``) gets synthkit from the wheel only, and its
dependencies from the test interpreter's site-packages through a ``.pth`` path line: the same
releases ``pip install`` resolved for this checkout, without downloading them again. A ``.pth``
path line is not processed as a site dir, so the editable install's finder there is not loaded
and the source tree is not importable: the test checks that ``synthkit`` and ``synthkit.cli``
come from the fresh venv. The installed package is made read-only (as a system or container
install is) before anything runs, so numba's kernel cache cannot go beside the sources.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from synthkit.methods import available_methods

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parent.parent
FASTEST_CONFIG = {
    "retarget": "retarget/facade.yaml",  # uses the numba graph-cut kernels: checks their cache
    "petri-synth": "petri-synth/building_ring.yaml",
    "symmetry-texture": "symmetry-texture/quilt.yaml",
}
"""The bundled config each method runs in the installed tool; a method not named here runs the
first config of ``configs/<method>/``."""

_SKIP = shutil.ignore_patterns(".venv", ".git", "out", "build", "dist", "*.egg-info", "__pycache__",
                               "bench-results", ".pytest_cache", ".ruff_cache")


def _run(cmd, *, env, cwd, timeout=600):
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, env=env, cwd=cwd, timeout=timeout)


def _as_unprivileged(cmd: list) -> list:
    """``cmd`` so that file modes bind: as is for a normal user; for root, without the
    DAC-override capabilities (setpriv). Skips when root cannot drop them."""
    if os.geteuid() != 0:
        return cmd
    setpriv = shutil.which("setpriv")
    wrap = [setpriv, "--bounding-set=-dac_override,-dac_read_search"] if setpriv else None
    if wrap is None or subprocess.run([*wrap, "true"], capture_output=True).returncode != 0:
        pytest.skip("running as root and cannot drop CAP_DAC_OVERRIDE to make the install read-only")
    return [*wrap, *cmd]


EXTRA_CONFIGS = [("surface-by-numbers", "surface-by-numbers/transfer-stripes.yaml")]
"""Further modes run from the wheel: surface-by-numbers' first config is a segmentation."""


def _config_for(method: str) -> str:
    if method in FASTEST_CONFIG:
        return FASTEST_CONFIG[method]
    configs = sorted((REPO / "configs" / method).glob("*.yaml"))
    assert configs, f"method {method} has no bundled config in configs/{method}/"
    return f"{method}/{configs[0].name}"


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv folder, its site-packages, a work folder holding copies of configs/ and data-samples/)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    shutil.copytree(REPO, src, ignore=_SKIP)  # build from a copy: no build/ or egg-info in the checkout
    wheels = tmp / "wheels"
    build = _run([sys.executable, "-m", "pip", "wheel", ".", "--no-deps", "--disable-pip-version-check",
                  "-w", wheels], env=os.environ.copy(), cwd=src)
    assert build.returncode == 0, build.stdout + build.stderr
    (wheel,) = wheels.glob("synthkit-*.whl")

    names = set(zipfile.ZipFile(wheel).namelist())
    sources = {f"synthkit/{p.relative_to(REPO / 'synthkit').as_posix()}" for p in (REPO / "synthkit").rglob("*.py")}
    sources |= {f"synthkit/cli/{p.relative_to(REPO / 'cli').as_posix()}" for p in (REPO / "cli").rglob("*.py")}
    assert not sources - names, f"modules missing from the wheel: {sorted(sources - names)}"

    venv = tmp / "venv"
    made = _run([sys.executable, "-m", "venv", "--without-pip", venv], env=os.environ.copy(), cwd=tmp)
    assert made.returncode == 0, made.stderr
    python = venv / "bin" / "python"
    site = Path(_run([python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                     env=os.environ.copy(), cwd=tmp).stdout.strip())
    deps = {sysconfig.get_path("purelib"), sysconfig.get_path("platlib")}
    (site / "zz_synthkit_test_dependencies.pth").write_text("".join(f"{d}\n" for d in sorted(deps)))
    install = _run([sys.executable, "-m", "pip", "--python", python, "install", "--no-deps", "--no-index",
                    "--disable-pip-version-check", wheel], env=os.environ.copy(), cwd=tmp)
    assert install.returncode == 0, install.stdout + install.stderr
    for folder in [site / "synthkit", *(site / "synthkit").rglob("*")]:
        if folder.is_dir():
            folder.chmod(0o555)

    work = tmp / "work"
    work.mkdir()
    shutil.copytree(REPO / "configs", work / "configs")
    shutil.copytree(REPO / "data-samples", work / "data-samples")
    yield venv, site, work
    for folder in [site / "synthkit", *(site / "synthkit").rglob("*")]:
        if folder.is_dir():
            folder.chmod(0o755)


def _env(home: Path, tmpdir: Path) -> dict[str, str]:
    """A clean environment: no PYTHONPATH, numba's cache choice left to synthkit and numba."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "VIRTUAL_ENV")}
    home.mkdir(parents=True, exist_ok=True)
    tmpdir.mkdir(parents=True, exist_ok=True)
    env.update(HOME=str(home), TMPDIR=str(tmpdir), PYTHONDONTWRITEBYTECODE="1")
    return env


def _kernel_cache_files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*.nbi"))


def test_installed_wheel_is_the_whole_tool(installed, tmp_path):
    venv, site, work = installed
    env = _env(tmp_path / "home", tmp_path / "tmp")
    synthkit = venv / "bin" / "synthkit"

    where = _run([venv / "bin" / "python", "-c",
                  "import sys, synthkit, synthkit.cli.main, synthkit.methods.symtex.pipeline; "
                  "print(synthkit.__file__); print(synthkit.cli.main.__file__); "
                  "print(synthkit.methods.symtex.pipeline.__file__); print(*sys.path, sep='\\n')"],
                 env=env, cwd=work)
    assert where.returncode == 0, where.stderr
    lines = where.stdout.splitlines()
    for module_file in lines[:3]:
        assert Path(module_file).is_relative_to(site), module_file
    assert not any(p and Path(p).resolve().is_relative_to(REPO) and not Path(p).resolve().is_relative_to(REPO / ".venv")
                   for p in lines[3:]), lines[3:]

    helped = _run(_as_unprivileged([synthkit, "--help"]), env=env, cwd=work)
    assert helped.returncode == 0 and helped.stderr == ""
    commands = helped.stdout.split("Commands:", 1)[1]
    listed = [line.split()[0] for line in commands.splitlines() if line.strip()]
    methods = available_methods()
    assert {"retarget", "petri-synth", "symmetry-texture"} <= set(methods)
    assert listed == [*methods, "init", "schema", "validate", "run", "report"]

    runs = [(method, _config_for(method)) for method in methods] + EXTRA_CONFIGS
    for method, config in runs:
        out = work / "out" / Path(config).stem
        proc = _run(_as_unprivileged([synthkit, method, f"configs/{config}", "--out", out,
                                      "--no-progress"]), env=env, cwd=work)
        assert proc.returncode == 0, proc.stderr
        assert re.fullmatch(rf"{re.escape(method)}: wrote {re.escape(str(out))} in [0-9.]+ s \(.*\)\n", proc.stderr), (
            proc.stderr)
        assert json.loads((out / "report.json").read_text())["status"] == "ok"

    # the installed package is read-only: numba kept the kernels in the user's cache, not beside them
    assert not list((site / "synthkit").rglob("*.nb[ic]"))
    assert {"graphcut", "flow"} <= {n.split(".")[0] for n in _kernel_cache_files(tmp_path / "home" / ".cache")}


def test_read_only_install_and_home_still_cache_the_kernels(installed, tmp_path):
    """Neither site-packages nor ~/.cache writable: numba alone would refuse to import the kernels
    (RuntimeError, exit 1); synthkit points its cache at a private folder in TMPDIR. Every method
    (and surface-by-numbers' transfer mode) runs that way."""
    venv, site, work = installed
    home = tmp_path / "home"
    env = _env(home, tmp_path / "tmp")
    runs = [(method, _config_for(method)) for method in available_methods()] + EXTRA_CONFIGS
    home.chmod(0o555)
    try:
        procs = []
        for method, config in runs:
            out = work / "out" / f"read-only-{Path(config).stem}"
            cmd = [venv / "bin" / "synthkit", method, f"configs/{config}", "--out", out, "--no-progress"]
            procs.append((method, out, _run(_as_unprivileged(cmd), env=env, cwd=work)))
    finally:
        home.chmod(0o755)
    for method, out, proc in procs:
        assert proc.returncode == 0, (method, proc.stderr)
        assert re.search(rf"{method}: wrote {re.escape(str(out))} in [0-9.]+ s", proc.stderr), proc.stderr
        assert json.loads((out / "report.json").read_text())["status"] == "ok"
    assert not list(home.iterdir())
    private = tmp_path / "tmp" / f"synthkit-numba-{os.getuid()}"
    assert private.stat().st_mode & 0o777 == 0o700
    assert {"graphcut", "flow"} <= {n.split(".")[0] for n in _kernel_cache_files(private)}
