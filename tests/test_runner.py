"""The runner: report.json contents, atomic outputs, overwrite rules, determinism."""

import json

import numpy as np
import pytest

from synthkit import __version__
from synthkit.errors import ConfigError, InputError
from synthkit.io.images import load_image
from synthkit.runner import run_config


def test_report_and_outputs(echo_config, tmp_path):
    out = tmp_path / "out"
    report = run_config(echo_config, out_dir=out, show_progress=False)
    on_disk = json.loads((out / "report.json").read_text())
    assert on_disk == json.loads(json.dumps(report))
    assert report["method"] == "echo" and report["version"] == __version__ and report["seed"] == 0
    assert report["config"]["mode"] == "invert"
    assert set(report["timings"]) == {"load", "process", "total"}
    assert report["timings"]["total"] >= report["timings"]["load"] + report["timings"]["process"]
    assert report["outputs"] == {"image": "result.png", "report": "report.json"}
    result = load_image(out / "result.png", mode="gray")
    expected = 1.0 - np.linspace(0.0, 1.0, 16).reshape(4, 4)
    np.testing.assert_allclose(result, expected, atol=1 / 255)
    assert report["metrics"]["mean"] == pytest.approx(0.5, abs=1e-6)
    assert not list(tmp_path.glob(".out.*")), "staging folder left behind"


def test_existing_output_needs_overwrite(echo_config, tmp_path):
    out = tmp_path / "out"
    run_config(echo_config, out_dir=out, show_progress=False)
    with pytest.raises(ConfigError, match="output folder exists; pass --overwrite"):
        run_config(echo_config, out_dir=out, show_progress=False)
    (out / "stale.txt").write_text("old")
    run_config(echo_config, out_dir=out, overwrite=True, overrides=["mode=copy"], show_progress=False)
    assert not (out / "stale.txt").exists()
    assert json.loads((out / "report.json").read_text())["config"]["mode"] == "copy"


def test_failed_run_leaves_previous_output_intact(echo_config, tmp_path):
    out = tmp_path / "out"
    run_config(echo_config, out_dir=out, show_progress=False)
    before = (out / "report.json").read_bytes()
    with pytest.raises(InputError, match="deliberately refused"):
        run_config(echo_config, out_dir=out, overwrite=True, overrides=["fail=input"], show_progress=False)
    assert (out / "report.json").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["echo.yaml", "in.png", "out"]


def test_failed_run_writes_nothing(echo_config, tmp_path):
    out = tmp_path / "fresh"
    with pytest.raises(ZeroDivisionError):
        run_config(echo_config, out_dir=out, overrides=["fail=crash"], show_progress=False)
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["echo.yaml", "in.png"]


def test_refuses_output_folder_holding_inputs(echo_config, tmp_path):
    with pytest.raises(ConfigError, match="output folder holds the input"):
        run_config(echo_config, out_dir=tmp_path, overwrite=True, show_progress=False)
    assert (tmp_path / "in.png").exists()


def test_seed_determinism(echo_config, tmp_path):
    a = run_config(echo_config, out_dir=tmp_path / "a", seed=5, show_progress=False)
    b = run_config(echo_config, out_dir=tmp_path / "b", seed=5, show_progress=False)
    c = run_config(echo_config, out_dir=tmp_path / "c", seed=6, show_progress=False)
    assert a["metrics"]["noise"] == b["metrics"]["noise"]
    assert a["metrics"]["noise"] != c["metrics"]["noise"]
    assert (tmp_path / "a" / "result.png").read_bytes() == (tmp_path / "b" / "result.png").read_bytes()


def test_refusal_keeps_diagnostics(echo_config, tmp_path):
    out = tmp_path / "out"
    with pytest.raises(InputError, match="refused after writing diagnostics"):
        run_config(echo_config, out_dir=out, overrides=["fail=refuse"], show_progress=False)
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "refused"
    assert report["error"].endswith("refused after writing diagnostics")
    assert report["metrics"] == {"why": "statistics kept", "ratio": None}
    assert (out / "diagnostic.png").is_file()


def test_numpy_metrics_become_plain_json(echo_config, tmp_path):
    report = run_config(echo_config, out_dir=tmp_path / "o", show_progress=False)
    assert type(report["metrics"]["noise"]) is int
    assert report["status"] == "ok"
    json.dumps(report, allow_nan=False)



def test_pipeline_errors_name_the_config(echo_config, tmp_path):
    """An error raised inside a pipeline names its input and value; the runner adds the config file once."""
    with pytest.raises(InputError) as info:
        run_config(echo_config, out_dir=tmp_path / "o", overrides=["fail=input"], show_progress=False)
    line = str(info.value)
    assert line.startswith(f"{echo_config}: ") and line.count(str(echo_config)) == 1
    assert line.endswith("in.png: deliberately refused")
    assert not (tmp_path / "o").exists()


def test_a_killed_unreaped_process_counts_as_gone():
    """A zombie (killed, not yet reaped: a Dask nanny reaps its killed worker a moment later) no
    longer runs, so its staging folder may be removed; a live process is kept."""
    import subprocess
    import time

    from synthkit.outdir import _pid_gone

    proc = subprocess.Popen(["sleep", "30"])
    try:
        assert not _pid_gone(proc.pid)
        proc.kill()
        deadline = time.monotonic() + 10
        while not _pid_gone(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert _pid_gone(proc.pid)  # a zombie until wait() below reaps it
    finally:
        proc.wait()
    assert _pid_gone(proc.pid)
