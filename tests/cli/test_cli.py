"""The click layer: help, version, exit codes, messages on stderr, JSON on stdout."""

import json
from pathlib import Path

import pytest

from synthkit import __version__
from synthkit.cli.main import cli


def test_help_lists_commands(runner):
    result = runner.invoke(cli, ["--help"])
    assert result.exit_code == 0
    assert "validate" in result.output and "run" in result.output
    assert "Exit codes: 0 success, 2 usage or config error, 3 input data error" in result.output


def test_version(runner):
    result = runner.invoke(cli, ["--version"])
    assert result.exit_code == 0 and result.output.strip() == f"synthkit, version {__version__}"


def test_unknown_subcommand_is_usage_error(runner):
    result = runner.invoke(cli, ["frobnicate"])
    assert result.exit_code == 2 and "No such command 'frobnicate'" in result.stderr


def test_validate_ok_and_bad(runner, echo_config, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("method: echo\nimage: in.png\nmod: copy\n")
    result = runner.invoke(cli, ["validate", str(echo_config), str(bad)])
    assert result.exit_code == 2
    assert f"ok: {echo_config} (echo, 1 input file(s))" in result.stderr
    assert "unknown key 'mod' (did you mean 'mode'?)" in result.stderr
    assert result.stdout == ""


def test_validate_missing_input_file_exit_3(runner, echo_config, tmp_path):
    missing = tmp_path / "missing.yaml"
    missing.write_text("method: echo\nimage: gone.png\n")
    bad = tmp_path / "bad.yaml"
    bad.write_text("method: echo\nimage: in.png\nmod: copy\n")
    result = runner.invoke(cli, ["validate", str(missing), str(bad)])
    assert result.exit_code == 3  # the first failure's code
    assert "image: file not found:" in result.stderr and "gone.png" in result.stderr
    result = runner.invoke(cli, ["validate", str(bad), str(missing)])
    assert result.exit_code == 2


def test_run_json_report_on_stdout(runner, echo_config, tmp_path):
    root = tmp_path / "runs"
    result = runner.invoke(cli, ["run", str(echo_config), "--out-root", str(root), "--json", "--seed", "3"])
    assert result.exit_code == 0, result.stderr
    payload = json.loads(result.stdout)
    assert payload[0]["ok"] and payload[0]["report"]["seed"] == 3
    assert (root / "echo" / "report.json").is_file()
    assert "run: 1 succeeded, 0 failed" in result.stderr


def _config(tmp_path, name, extra):
    path = tmp_path / f"{name}.yaml"
    path.write_text(f"method: echo\nimage: in.png\n{extra}")
    return str(path)


def test_run_continues_past_failures_and_exits_with_first_code(runner, echo_config, tmp_path):
    configs = [
        _config(tmp_path, "a_input", "fail: input\n"),
        _config(tmp_path, "b_ok", ""),
        _config(tmp_path, "c_config", "gain: 0\n"),
        _config(tmp_path, "d_crash", "fail: crash\n"),
    ]
    result = runner.invoke(cli, ["run", *configs, "--out-root", str(tmp_path / "o")])
    assert result.exit_code == 3
    assert "run: 1 succeeded, 3 failed" in result.stderr
    assert "deliberately refused" in result.stderr
    assert "gain: Input should be greater than 0" in result.stderr
    assert "internal error: ZeroDivisionError: deliberate crash (run with -v for the traceback)" in result.stderr
    assert "Traceback" not in result.stderr
    assert (tmp_path / "o" / "b_ok" / "result.png").is_file()
    assert not (tmp_path / "o" / "a_input").exists()


def test_run_verbose_shows_traceback(runner, echo_config, tmp_path):
    cfg = _config(tmp_path, "crash", "fail: crash\n")
    result = runner.invoke(cli, ["-v", "run", cfg, "--out-root", str(tmp_path / "o")])
    assert result.exit_code == 1 and "Traceback" in result.stderr


def test_run_config_error_exit_2(runner, echo_config, tmp_path):
    result = runner.invoke(cli, ["run", str(tmp_path / "missing.yaml"), "--out-root", str(tmp_path / "o")])
    assert result.exit_code == 2 and "missing.yaml: config file not found" in result.stderr


def test_run_rejects_clashing_names(runner, echo_config, tmp_path):
    sub = tmp_path / "sub"
    sub.mkdir()
    other = sub / "echo.yaml"
    other.write_text(echo_config.read_text())
    result = runner.invoke(cli, ["run", str(echo_config), str(other)])
    assert result.exit_code == 2 and "share output names" in result.stderr


def test_run_bad_set_syntax(runner, echo_config, tmp_path):
    result = runner.invoke(cli, ["run", str(echo_config), "--set", "gain", "--out-root", str(tmp_path / "o")])
    assert result.exit_code == 2 and "--set 'gain': expected key.path=value" in result.stderr


def test_quiet_silences_summary(runner, echo_config, tmp_path):
    result = runner.invoke(cli, ["-q", "run", str(echo_config), "--out-root", str(tmp_path / "o")])
    assert result.exit_code == 0 and result.stderr == "" and result.stdout == ""


@pytest.fixture
def echo_command(echo_method):
    from synthkit.cli.options import method_command

    return method_command("echo", "Echo an image.", flags={"--dark": ("gain=0.5", "Halve the image.")})


def test_method_command_success_json_and_flag(runner, echo_command, echo_config, tmp_path):
    out = tmp_path / "o"
    result = runner.invoke(echo_command, [str(echo_config), "--out", str(out), "--json", "--dark", "--no-progress"])
    assert result.exit_code == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["config"]["gain"] == 0.5
    assert report["metrics"]["mean"] == pytest.approx(0.25, abs=1e-6)
    assert result.stderr.startswith(f"echo: wrote {out} in ")


@pytest.mark.parametrize(
    ("extra", "code", "message"),
    [
        (["--set", "gain=-1"], 2, "gain: Input should be greater than 0 (got -1)"),
        (["--set", "fail=input"], 3, "deliberately refused"),
        (["--set", "fail=crash"], 1, "internal error: ZeroDivisionError"),
        (["--seed", "-4"], 2, "Invalid value for '--seed'"),
    ],
)
def test_method_command_exit_codes(runner, echo_command, echo_config, tmp_path, extra, code, message):
    result = runner.invoke(echo_command, [str(echo_config), "--out", str(tmp_path / "o"), *extra])
    assert result.exit_code == code
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "o").exists()


def test_method_command_existing_output(runner, echo_command, echo_config, tmp_path):
    out = tmp_path / "o"
    assert runner.invoke(echo_command, [str(echo_config), "--out", str(out)]).exit_code == 0
    again = runner.invoke(echo_command, [str(echo_config), "--out", str(out)])
    assert again.exit_code == 2 and "output folder exists; pass --overwrite" in again.stderr
    assert runner.invoke(echo_command, [str(echo_config), "--out", str(out), "--overwrite"]).exit_code == 0


def test_degraded_output_warns_and_strict_exits_3(runner, echo_command, echo_config, tmp_path):
    out = tmp_path / "o"
    result = runner.invoke(cli, ["echo", str(echo_config), "--out", str(out), "--set", "fail=degrade"])
    assert result.exit_code == 0
    assert result.stderr.splitlines()[0] == "WARNING synthkit: mesh: open_edges 9 over its limit 8 (input: 4)"
    assert result.stderr.splitlines()[1].endswith("[degraded]")
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "degraded"
    assert report["metrics"]["mesh_quality"]["mesh"] == {"input": {"open_edges": 4}, "output": {"open_edges": 9},
                                                         "limits": {"open_edges": 8}}
    strict = runner.invoke(cli, ["--strict", "echo", str(echo_config), "--out", str(tmp_path / "s"),
                                 "--set", "fail=degrade"])
    assert strict.exit_code == 3
    assert strict.stderr.strip().splitlines()[-1] == (
        f"error: {echo_config}: output degraded (--strict): mesh: open_edges 9 over its limit 8 (input: 4)")
    assert json.loads((tmp_path / "s" / "report.json").read_text())["status"] == "degraded"


def test_batch_row_of_degraded_run(runner, echo_config, tmp_path):
    for strict, code in (([], 0), (["--strict"], 3)):
        root = tmp_path / f"root{len(strict)}"
        args = [*strict, "run", str(echo_config), "--out-root", str(root), "--set", "fail=degrade"]
        result = runner.invoke(cli, args)
        assert result.exit_code == code
        row = json.loads((root / "batch.json").read_text())["runs"][0]
        assert (row["status"], row["exit_code"]) == ("degraded", code)


def test_max_memory_nan_is_a_usage_error(runner, echo_config):
    result = runner.invoke(cli, ["--max-memory", "nan", "run", str(echo_config)])
    assert result.exit_code == 2
    assert "nan is not a number" in result.stderr


def test_run_writes_the_review_page_and_rows_name_folders_and_previews(runner, echo_config, tmp_path):
    root = tmp_path / "o"
    refused = _config(tmp_path, "refused", "fail: refuse\n")
    result = runner.invoke(cli, ["run", str(echo_config), refused, "--out-root", str(root)])
    assert result.exit_code == 3
    assert f"review: {root / 'index.html'}" in result.stderr
    rows = json.loads((root / "batch.json").read_text())["runs"]
    assert [(r["status"], Path(r["out"]).name, r["preview"]) for r in rows] == [
        ("ok", "echo", "result.png"), ("failed", "refused", "diagnostic.png")]
    page = (root / "index.html").read_text()
    assert page.count('class="card"') == 2 and "refused after writing diagnostics" in page
    again = runner.invoke(cli, ["report", str(root)])
    assert again.exit_code == 0 and again.stderr.strip() == f"review: {root / 'index.html'}"


def test_global_options_after_the_method_name(runner, echo_config, tmp_path):
    quiet = runner.invoke(cli, ["echo", str(echo_config), "--out", str(tmp_path / "a"), "-q"])
    assert quiet.exit_code == 0 and quiet.stderr == ""
    strict = runner.invoke(cli, ["echo", str(echo_config), "--out", str(tmp_path / "b"), "--strict",
                                 "--set", "fail=degrade"])
    assert strict.exit_code == 3
    small = runner.invoke(cli, ["run", str(echo_config), "--out-root", str(tmp_path / "c"), "--max-memory", "nan"])
    assert small.exit_code == 2 and "nan is not a number" in small.stderr


def test_a_sweep_key_applies_only_to_configs_whose_method_has_it(runner, echo_config, tmp_path):
    from synthkit import plan

    kept, dropped = plan.axes_for("retarget", [("gain", ["1"]), ("seed", ["1", "2"]), ("analysis.tau", ["0.1"])])
    assert ([k for k, _ in kept], dropped) == (["seed", "analysis.tau"], ["gain"])
    root = tmp_path / "o"
    result = runner.invoke(cli, ["run", str(echo_config), "--out-root", str(root), "--sweep", "gain=1,2",
                                 "--sweep", "analysis.tau=0.1"])
    assert result.exit_code == 0, result.stderr
    assert f"note: {echo_config} has no key analysis.tau; it runs once for that sweep" in result.stderr
    assert sorted(p.name for p in root.iterdir() if p.name.startswith("echo")) == ["echo__gain-1", "echo__gain-2"]


def test_batch_file_sweep_values_parse_as_on_the_command_line(tmp_path):
    from synthkit import plan

    spec = tmp_path / "study.yaml"
    spec.write_text("configs: [a.yaml]\nsweep:\n  target.axis_steps: ['{y: 1}', {z: 2}]\n")
    axes = plan.read_batch_file(str(spec)).axes
    assert axes == [("target.axis_steps", ["{y: 1}", '{"z": 2}'])]
    assert plan.parse_sweep("target.axis_steps={y: 1}")[1] == ["{y: 1}"]


def test_validate_accepts_a_batch_file_and_checks_its_sweeps(runner, echo_config, tmp_path):
    spec = tmp_path / "study.yaml"
    spec.write_text(f"configs: [{echo_config.name}]\nset: {{mode: copy}}\nsweep: {{gain: [0.5, 2]}}\n")
    ok = runner.invoke(cli, ["validate", str(spec)])
    assert ok.exit_code == 0 and f"ok: {spec} (batch file, 1 configs, 3 checks)" in ok.stderr
    spec.write_text(f"configs: [{echo_config.name}]\nsweep: {{gain: [0.5, 20]}}\n")
    bad = runner.invoke(cli, ["validate", str(spec)])
    assert bad.exit_code == 2 and "gain: Input should be less than or equal to 10" in bad.stderr


def test_name_outputs_links_the_summary_and_main_result_under_the_run_name(runner, echo_config, tmp_path):
    from synthkit.summary import main_output

    root = tmp_path / "o"
    result = runner.invoke(cli, ["run", str(echo_config), "--out-root", str(root), "--name-outputs"])
    assert result.exit_code == 0, result.stderr
    folder = root / "echo"
    assert (folder / "echo.preview.png").read_bytes() == (folder / "result.png").read_bytes()
    report = json.loads((folder / "report.json").read_text())
    assert report["outputs"]["named_preview"] == "echo.preview.png"
    assert main_output({"labels_ply": "labels.ply", "transferred": "t.obj"}, "surface-by-numbers") == "t.obj"
    assert main_output({"mesh_wall": "wall.obj", "report": "report.json"}, "reshape") == "wall.obj"
    assert main_output({"report": "report.json"}, "reshape") is None
