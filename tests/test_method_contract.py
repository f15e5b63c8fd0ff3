"""One battery over every registered method (as scikit-learn's ``check_estimator`` over every
estimator): a method added to :data:`synthkit.methods.METHODS` with a bundled config gets it for
free. On each method's smallest bundled config (by the size of its input files): the config round
trip, the schema's defaults, keyed errors of the command line, determinism, and a run in memory
that writes nothing and reports what the command line's run reports. Every mesh output of every
bundled config is opened by Blender and the Khronos validator in ``tests/clients``."""

import json
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from synthkit.cli.main import cli
from synthkit.errors import ConfigError
from synthkit.methods import available_methods, spec
from synthkit.runner import load_method_config, run_config

REPO = Path(__file__).resolve().parents[1]
METHODS = available_methods()


def smallest_config(name: str) -> Path:
    """The bundled config of method ``name`` whose input files are smallest in all."""
    def size(path: Path) -> int:
        return sum(p.stat().st_size for p in load_method_config(path)[2])

    return min(sorted((REPO / "configs" / name).glob("*.yaml")), key=size)


def _dumped(path: Path) -> dict:
    return load_method_config(path)[1].model_dump(mode="json")


@pytest.mark.parametrize("name", METHODS)
def test_config_round_trip(name, tmp_path):
    """A config dumped (paths resolved) and read again is the same config."""
    first = _dumped(smallest_config(name))
    again = tmp_path / "again.yaml"
    again.write_text(yaml.safe_dump(first))
    assert _dumped(again) == first


@pytest.mark.parametrize("name", METHODS)
def test_the_init_template_holds_the_schemas_defaults(name, tmp_path):
    """``synthkit init``'s config, its inputs filled, validates, and writes the schema's default for
    every key the method's spec gives no example value."""
    text = CliRunner().invoke(cli, ["init", name]).stdout
    some_input = load_method_config(smallest_config(name))[2][0]
    path = tmp_path / "init.yaml"
    path.write_text(text.replace("null  # REQUIRED", f'"{some_input}"  # REQUIRED'))
    _, cfg, _ = load_method_config(path)
    examples = {key.split(".")[0] for key in (*spec(name).init_values, *spec(name).init_required)}
    written = yaml.safe_load(path.read_text())
    schema = type(cfg).model_construct().model_dump(mode="json")
    defaults = {k: schema[k] for k, f in type(cfg).model_fields.items() if not f.is_required() and k not in examples}
    assert defaults and {k: written[k] for k in defaults} == defaults


@pytest.mark.parametrize("name", METHODS)
def test_an_unknown_key_names_the_file_and_the_key(name):
    path = smallest_config(name)
    with pytest.raises(ConfigError, match=rf"^{path}: unknown key 'no_such_key'"):
        load_method_config(path, overrides=["no_such_key=1"])


@pytest.mark.parametrize("name", METHODS)
def test_a_bad_value_is_one_line_with_exit_code_2(name):
    """``synthkit validate --set seed=-1``: exit 2, one line naming the file and the key, no traceback."""
    path = smallest_config(name)
    result = CliRunner().invoke(cli, ["validate", str(path), "--set", "seed=-1"])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}") and "seed" in lines[0], result.stderr
    assert "Traceback" not in result.stderr


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name not in ("report.json", ".synthkit-output")}


def _untimed(value):
    """``value`` without timings (keys ending in ``seconds`` or ``_ms``), at every depth."""
    if isinstance(value, dict):
        return {k: _untimed(v) for k, v in value.items() if not k.endswith(("seconds", "_ms"))}
    if isinstance(value, list):
        return [_untimed(v) for v in value]
    return value


@pytest.mark.slow
@pytest.mark.parametrize("name", METHODS)
def test_same_seed_same_bytes_and_in_memory_the_same_result(name, tmp_path, monkeypatch, refuse_writes):
    """Two command-line runs with one seed write the same bytes and metrics; the same config run in
    memory (the Python functions' road) writes nothing and reports the same metrics."""
    import synthkit.methods.rooms as rooms
    from synthkit.api import run_in_memory
    from synthkit.io.inputs import Inputs
    from synthkit.result import Result

    path = smallest_config(name)
    reports = [run_config(path, out_dir=tmp_path / which, seed=11, show_progress=False) for which in ("a", "b")]
    a, b = _files(tmp_path / "a"), _files(tmp_path / "b")
    assert a and a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []
    assert _untimed(reports[0]["metrics"]) == _untimed(reports[1]["metrics"])
    _, cfg, _ = load_method_config(path, seed=11)
    (tmp_path / "cwd").mkdir()
    refuse_writes(monkeypatch, tmp_path / "cwd")
    result = run_in_memory(name, name, rooms.pipeline_module(name).compute, cfg, Inputs())
    assert list((tmp_path / "cwd").iterdir()) == []
    assert isinstance(result, Result)
    in_memory = json.loads(json.dumps(_untimed(result.metrics), default=str))
    assert set(in_memory) == set(_untimed(reports[0]["metrics"]))
    headline = [k for k in spec(name).headline if k in reports[0]["metrics"]]
    assert {k: in_memory[k] for k in headline} == {k: reports[0]["metrics"][k] for k in headline}
