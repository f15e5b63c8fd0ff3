"""Hostile use of the CLI (issue 17): nothing outside a run's own output folder may change, every
refusal is one line with its exit code, signals and concurrent runs leave no half folder."""

import hashlib
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from synthkit.cli.main import cli
from synthkit.config import YAML_NODE_BUDGET
from synthkit.errors import ConfigError
from synthkit.limits import Budget
from synthkit.methods import available_methods, spec
from synthkit.outdir import MARKER, move_into_place, target_lock

REPO = Path(__file__).resolve().parents[2]
CONFIGS = REPO / "configs"
SYNTHKIT = [sys.executable, "-c", "from synthkit.cli.main import main; main()"]


def snapshot(root: Path, *, exclude: Path | None = None) -> dict[str, str]:
    """SHA-256 of every file and symlink target under ``root`` (folders as 'dir'), minus ``exclude``."""
    found = {}
    for path in sorted(root.rglob("*")):
        if exclude is not None and (path == exclude or exclude in path.parents):
            continue
        rel = path.relative_to(root).as_posix()
        if path.is_symlink():
            found[rel] = "link:" + os.readlink(path)
        elif path.is_dir():
            found[rel] = "dir"
        else:
            found[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
    return found


def one_error_line(result) -> str:
    """The single stderr line of a refused run (asserts there is exactly one, and no traceback)."""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    return lines[0]


@pytest.fixture
def user_tree(tmp_path, echo_config):
    """A user's folder beside the echo config: files that no run may touch."""
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "keep.bin").write_bytes(b"\x00\x01")
    return tmp_path


# -- 1. what --overwrite may replace ------------------------------------------------------------


def test_dotdot_config_stem_refused_under_out_root(runner, user_tree):
    cfg = user_tree / "cfgs" / "...yaml"
    cfg.parent.mkdir()
    cfg.write_text(f"method: echo\nimage: {user_tree / 'in.png'}\n")
    root = user_tree / "root" / "R"
    root.mkdir(parents=True)
    (user_tree / "root" / "sibling.txt").write_text("beside R")
    before = snapshot(user_tree)
    result = runner.invoke(cli, ["run", str(cfg), "--out-root", str(root), "--overwrite"])
    assert result.exit_code == 2
    assert "cannot name an output folder '..' after this config" in result.stderr
    assert "run: 0 succeeded, 1 failed" in result.stderr
    after = snapshot(user_tree, exclude=root / "batch.json")
    assert after == before


def test_dotdot_config_stem_refused_as_default_out(runner, user_tree, monkeypatch):
    cfg = user_tree / "...yaml"
    cfg.write_text(f"method: echo\nimage: {user_tree / 'in.png'}\n")
    monkeypatch.chdir(user_tree)
    before = snapshot(user_tree)
    result = runner.invoke(cli, ["echo", str(cfg), "--overwrite"])
    assert result.exit_code == 2
    assert one_error_line(result) == (
        f"error: {cfg}: cannot name an output folder '..' after this config; rename the file or give --out"
    )
    assert snapshot(user_tree) == before


def test_out_holding_the_input_through_a_symlink_is_refused(runner, user_tree):
    folder = user_tree / "album"
    folder.mkdir()
    (folder / "link.png").symlink_to(user_tree / "in.png")
    (folder / "other.txt").write_text("user file")
    cfg = user_tree / "linked.yaml"
    cfg.write_text("method: echo\nimage: album/link.png\n")
    before = snapshot(user_tree)
    result = runner.invoke(cli, ["echo", str(cfg), "--out", str(folder), "--overwrite"])
    assert result.exit_code == 2
    assert f"output folder holds the input {folder / 'link.png'}" in one_error_line(result)
    assert snapshot(user_tree) == before


@pytest.mark.parametrize("overwrite", [[], ["--overwrite"]])
def test_folder_that_is_not_a_synthkit_output_is_never_replaced(runner, user_tree, echo_config, overwrite):
    before = snapshot(user_tree)
    result = runner.invoke(cli, ["echo", str(echo_config), "--out", str(user_tree / "data"), *overwrite])
    assert result.exit_code == 2
    assert one_error_line(result) == (
        f"error: --out {user_tree / 'data'}: folder exists and is not a synthkit output "
        f"(no {MARKER} and report.json); refusing to replace it"
    )
    assert snapshot(user_tree) == before


def test_report_without_marker_is_not_enough(runner, user_tree, echo_config):
    fake = user_tree / "looks_like_output"
    fake.mkdir()
    (fake / "report.json").write_text("{}")
    before = snapshot(user_tree)
    result = runner.invoke(cli, ["echo", str(echo_config), "--out", str(fake), "--overwrite"])
    assert result.exit_code == 2 and "is not a synthkit output" in result.stderr
    assert snapshot(user_tree) == before


def test_previous_output_is_replaced_only_with_overwrite(runner, user_tree, echo_config):
    out = user_tree / "out"
    assert runner.invoke(cli, ["echo", str(echo_config), "--out", str(out)]).exit_code == 0
    marker = json.loads((out / MARKER).read_text())
    assert marker["host"] == socket.gethostname() and marker["synthkit"]
    first = snapshot(out)
    result = runner.invoke(cli, ["echo", str(echo_config), "--out", str(out), "--set", "mode=copy"])
    assert result.exit_code == 2 and "output folder exists; pass --overwrite" in one_error_line(result)
    assert snapshot(out) == first
    before = snapshot(user_tree, exclude=out)
    result = runner.invoke(cli, ["echo", str(echo_config), "--out", str(out), "--set", "mode=copy", "--overwrite"])
    assert result.exit_code == 0, result.stderr
    assert json.loads((out / "report.json").read_text())["config"]["mode"] == "copy"
    assert snapshot(user_tree, exclude=out) == before


def test_out_that_is_a_symlink_is_refused(runner, user_tree, echo_config):
    real = user_tree / "real_out"
    assert runner.invoke(cli, ["echo", str(echo_config), "--out", str(real)]).exit_code == 0
    (user_tree / "alias").symlink_to(real)
    before = snapshot(user_tree)
    result = runner.invoke(cli, ["echo", str(echo_config), "--out", str(user_tree / "alias"), "--overwrite"])
    assert result.exit_code == 2 and "is a symbolic link" in one_error_line(result)
    assert snapshot(user_tree) == before


# -- 2. concurrency and signals -----------------------------------------------------------------


def test_a_held_lock_refuses_a_second_run(runner, user_tree, echo_config):
    out = user_tree / "busy"
    before = snapshot(user_tree)
    with target_lock(out):
        result = runner.invoke(cli, ["echo", str(echo_config), "--out", str(out)])
    assert result.exit_code == 2
    assert one_error_line(result) == f"error: --out {out}: another synthkit run is writing this folder"
    assert snapshot(user_tree) == before


def test_final_move_refuses_a_target_that_appeared(tmp_path):
    staging, target = tmp_path / ".t.partial-1", tmp_path / "t"
    staging.mkdir()
    (staging / "a.txt").write_text("new")
    target.mkdir()
    (target / "b.txt").write_text("first run")
    with pytest.raises(ConfigError, match="output folder appeared during the run; not replaced"):
        move_into_place(staging, target, overwrite=False)
    assert (target / "b.txt").read_text() == "first run" and not (target / "a.txt").exists()
    with pytest.raises(ConfigError, match="appeared during the run"):
        move_into_place(staging, target, overwrite=True)  # not a synthkit output
    assert sorted(p.name for p in target.iterdir()) == ["b.txt"]


@pytest.mark.slow
def test_two_processes_into_one_new_out_one_is_refused(tmp_path):
    out = tmp_path / "shared"
    cmd = [*SYNTHKIT, "-q", "symmetry-texture", str(CONFIGS / "symmetry-texture" / "quilt.yaml"), "--out", str(out),
           "--no-progress"]
    procs = [subprocess.Popen(cmd, cwd=tmp_path, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(p.communicate(timeout=300)[1], p.returncode)[::-1] for p in procs]
    codes = sorted(code for code, _ in results)
    assert codes == [0, 2], results
    refused = next(err for code, err in results if code == 2).strip().splitlines()
    assert len(refused) == 1 and refused[0].startswith(f"error: --out {out}: ")
    assert json.loads((out / "report.json").read_text())["status"] == "ok"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shared"]


@pytest.mark.slow
def test_sigterm_exits_143_and_removes_staging(tmp_path):
    out = tmp_path / "big"
    # this guided transfer runs for a minute or more: the signal always reaches a run in progress
    cmd = [*SYNTHKIT, "symmetry-texture", str(CONFIGS / "symmetry-texture" / "transfer.yaml"), "--out", str(out),
           "--no-progress", "--set", "output_size=[256, 256]", "--set", "synth.sweeps=20"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".big.partial-*")) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert list(tmp_path.glob(".big.partial-*")), "the run never started staging"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143
    assert err.strip().splitlines() == ["error: terminated (SIGTERM)"]
    assert list(tmp_path.iterdir()) == []


def test_sigterm_swallowed_by_a_library_still_ends_the_run(runner, user_tree, echo_config, monkeypatch):
    """OpenCV's import runs a bare ``except:``; a SIGTERM handled inside it was lost and the run
    exited 0. Here the load swallows it the same way: the run still ends at the stage's end with
    exit 143, leaving neither output nor staging folder."""
    import synthkit.io.inputs as inputs
    from synthkit.errors import TERMINATION_REQUESTED, Terminated

    real_load = inputs.load_image

    def load_swallowing_sigterm(*args, **kwargs):
        try:
            TERMINATION_REQUESTED.set()
            raise Terminated()
        except:  # noqa: E722 - what the library does
            pass
        return real_load(*args, **kwargs)

    monkeypatch.setattr(inputs, "load_image", load_swallowing_sigterm)
    before = snapshot(user_tree)
    try:
        result = runner.invoke(cli, ["echo", str(echo_config), "--out", str(user_tree / "out")])
    finally:
        TERMINATION_REQUESTED.clear()
    assert result.exit_code == 143, result.stderr
    assert result.stderr.strip() == "error: terminated (SIGTERM)"
    assert snapshot(user_tree) == before


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_leftovers_of_dead_runs_are_removed_others_kept(runner, user_tree, echo_config):
    out = user_tree / "out"
    dead = user_tree / f".out.partial-{_dead_pid()}"
    dead.mkdir()
    (dead / MARKER).write_text(json.dumps({"synthkit": "0.1.0", "host": socket.gethostname(), "pid": _dead_pid()}))
    (dead / "half.png").write_bytes(b"half")
    alive = user_tree / ".out.partial-1"  # pid 1 is alive
    alive.mkdir()
    (alive / MARKER).write_text(json.dumps({"synthkit": "0.1.0", "host": socket.gethostname(), "pid": 1}))
    stranger = user_tree / ".out.partial-2"  # no marker, pid 2 alive: not ours
    stranger.mkdir()
    unstarted = user_tree / f".out.partial-{_dead_pid()}"  # killed between mkdir and its marker
    unstarted.mkdir()
    (unstarted / MARKER).write_text("")
    unmarked = user_tree / f".out.partial-{_dead_pid()}"  # no marker, holds a file: kept
    unmarked.mkdir()
    (unmarked / "notes.txt").write_text("mine")
    before = snapshot(user_tree, exclude=dead)
    result = runner.invoke(cli, ["echo", str(echo_config), "--out", str(out)])
    assert result.exit_code == 0, result.stderr
    assert not dead.exists() and not unstarted.exists()
    assert alive.is_dir() and stranger.is_dir() and (unmarked / "notes.txt").read_text() == "mine"
    before.pop(f"{unstarted.name}/{MARKER}"), before.pop(unstarted.name)
    assert snapshot(user_tree, exclude=out) == before


# -- 3. resources bounded before the work starts ------------------------------------------------

BOMB = "".join(
    f"{name}: &{name} [{', '.join([f'*{prev}'] * 9) if prev else ', '.join(['lol'] * 9)}]\n"
    for prev, name in zip([None, *"abcdefgh"], "abcdefghi", strict=True)
)


def test_yaml_alias_bomb_refused_fast(runner, tmp_path, echo_method):
    cfg = tmp_path / "bomb.yaml"
    cfg.write_text("method: echo\n" + BOMB)
    start = time.perf_counter()
    result = runner.invoke(cli, ["run", str(cfg), "--out-root", str(tmp_path / "o"), "--set", "seed=1"])
    assert time.perf_counter() - start < 10
    assert result.exit_code == 2
    assert f"YAML aliases expand past {YAML_NODE_BUDGET} nodes; refusing to expand them" in result.stderr


def test_duplicate_key_refused(runner, tmp_path, echo_config):
    cfg = tmp_path / "dup.yaml"
    cfg.write_text("method: echo\nimage: in.png\nseed: 1\nseed: 2\n")
    result = runner.invoke(cli, ["validate", str(cfg)])
    assert result.exit_code == 2
    assert one_error_line(result) == f"error: {cfg}: line 4: duplicate key 'seed' (first at line 3)"


@pytest.mark.parametrize("value", [".nan", ".inf", "-.inf"])
def test_non_finite_float_refused(runner, tmp_path, echo_config, value):
    result = runner.invoke(cli, ["validate", str(echo_config), "--set", f"filter.sigma={value}"])
    assert result.exit_code == 2
    assert "filter.sigma: Input should be a finite number" in one_error_line(result)


RETARGET = CONFIGS / "retarget" / "bookshelf.yaml"
PETRI = CONFIGS / "petri-synth" / "building_curve.yaml"
QUILT = CONFIGS / "symmetry-texture" / "quilt.yaml"


@pytest.mark.parametrize(
    ("config", "override", "expected"),
    [
        (RETARGET, "analysis.dense_radius=1e-4", r"analysis\.dense_radius: 0\.0001 needs about \S+ samples \(limit "),
        (RETARGET, "analysis.dense_radius=1e-308", r"analysis\.dense_radius: 1e-308 needs unboundedly many samples"),
        (PETRI, "construction.points=[[0, 0], [1.0e+7, 0]]",
         r"construction\.points: 1e\+07 units long needs about 5e\+07 cells \(limit "),
        (QUILT, "output_size=[1000000, 1000000]", r"output_size: 1000000x1000000 needs about 1e\+12 pixels \(limit "),
    ],
)
def test_oversized_work_refused_before_it_starts(runner, tmp_path, config, override, expected):
    out = tmp_path / "o"
    start = time.perf_counter()
    result = runner.invoke(cli, ["run", str(config), "--out-root", str(out), "--set", override, "--no-progress"])
    assert time.perf_counter() - start < 60
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert re.search(expected, lines[0]), lines[0]
    assert "--max-memory raises it" in lines[0]
    assert sorted(p.name for p in out.iterdir()) == ["batch.json"]


def test_max_memory_lowers_and_raises_the_limit(runner, tmp_path):
    result = runner.invoke(cli, ["--max-memory", "0.01", "symmetry-texture", str(QUILT), "--out", str(tmp_path / "q")])
    assert result.exit_code == 2
    assert "output_size: 160x160 needs about 2.6e+04 pixels (limit 2.1e+04 at 0.01 GiB" in one_error_line(result)
    assert not (tmp_path / "q").exists()
    result = runner.invoke(cli, ["--max-memory", "1", "symmetry-texture", str(QUILT), "--out", str(tmp_path / "q"),
                                 "--no-progress"])
    assert result.exit_code == 0, result.stderr


def test_budget_limits_are_exact():
    budget = Budget(1000)
    assert budget.limit(10) == 100
    budget.require("k", 1, 100, "items", bytes_each=10)
    with pytest.raises(ConfigError, match=r"^k: 1 needs about 1e\+02 items \(limit 99 at "):
        budget.require("k", 1, 100, "items", bytes_each=10.1)
    with pytest.raises(ConfigError, match="needs unboundedly many items"):
        budget.require("k", 1, float("inf"), "items", bytes_each=1)


@pytest.mark.parametrize("point", ["[.nan, 0]", "[1.0e+308, 0]"])
def test_bad_curve_points_refused(runner, point):
    result = runner.invoke(cli, ["validate", str(PETRI), "--set", f"construction.points=[[0, 0], {point}]"])
    assert result.exit_code == 2
    assert "construction.points.1.0: Input should be" in one_error_line(result)


# -- 4. one line, the right code ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["echo", "CFG", "--seed", "abc"], "error: Invalid value for '--seed': 'abc' is not a valid integer range."),
        (["echo", "CFG", "--seed", "-1"],
         "error: Invalid value for '--seed': -1 is not in the range 0<=x<=4294967295."),
        (["echo", "DIR"], "error: Invalid value for 'CONFIG': File 'DIR' is a directory."),
        (["echo", "CFG", "--out", "FILE"], "error: Invalid value for '--out': Directory 'FILE' is a file."),
        (["frobnicate"], "error: No such command 'frobnicate'."),
    ],
)
def test_usage_errors_are_one_line(runner, tmp_path, echo_config, args, expected):
    names = {"CFG": str(echo_config), "DIR": str(tmp_path), "FILE": str(tmp_path / "in.png")}
    args = [names.get(a, a) for a in args]
    before = snapshot(tmp_path)
    result = runner.invoke(cli, args)
    assert result.exit_code == 2
    for key, value in names.items():
        expected = expected.replace(f"'{key}'", f"'{value}'")
    assert one_error_line(result) == expected
    assert snapshot(tmp_path) == before


def test_misspelt_required_key_says_did_you_mean(runner, tmp_path):
    cfg = tmp_path / "typo.yaml"
    cfg.write_text("method: retarget\ninptu: mesh.obj\n")
    result = runner.invoke(cli, ["validate", str(cfg)])
    assert result.exit_code == 2
    assert one_error_line(result) == (
        f"error: {cfg}: missing required key 'input' (found unknown key 'inptu': did you mean 'input'?)"
    )


def test_run_summary_names_each_failure_and_writes_batch_json(runner, tmp_path, echo_config):
    bad = tmp_path / "bad.yaml"
    bad.write_text("method: echo\nimage: in.png\ngain: 0\n")
    crash = tmp_path / "crash.yaml"
    crash.write_text("method: echo\nimage: in.png\nfail: input\n")
    root = tmp_path / "o"
    result = runner.invoke(cli, ["run", str(echo_config), str(bad), str(crash), "--out-root", str(root)])
    assert result.exit_code == 2
    tail = result.stderr.strip().splitlines()[-3:]
    assert tail[0] == "run: 1 succeeded, 2 failed"
    assert tail[1] == f"  failed: {bad} (exit 2): {bad}: gain: Input should be greater than 0 (got 0)"
    assert tail[2].startswith(f"  failed: {crash} (exit 3): ") and tail[2].endswith("deliberately refused")
    batch = json.loads((root / "batch.json").read_text())
    rows = {Path(r["config"]).name: r for r in batch["runs"]}
    assert [rows[n]["status"] for n in ("echo.yaml", "bad.yaml", "crash.yaml")] == ["ok", "failed", "failed"]
    assert [rows[n]["exit_code"] for n in ("echo.yaml", "bad.yaml", "crash.yaml")] == [0, 2, 3]
    assert rows["echo.yaml"]["out"] == str(root / "echo") and rows["echo.yaml"]["seconds"] > 0
    assert "gain: Input should be greater than 0" in rows["bad.yaml"]["error"]
    assert sorted(p.name for p in root.iterdir()) == ["batch.json", "echo", "index.html", "review"]


def test_foreign_batch_json_is_not_replaced(runner, tmp_path, echo_config):
    root = tmp_path / "o"
    root.mkdir()
    (root / "batch.json").write_text('{"mine": true}')
    result = runner.invoke(cli, ["run", str(echo_config), "--out-root", str(root)])
    assert result.exit_code == 0
    assert (root / "batch.json").read_text() == '{"mine": true}'
    assert "was not written by synthkit; batch.json not written" in result.stderr


# -- 6. configs a user can discover ---------------------------------------------------------------


@pytest.mark.parametrize("method", available_methods())
def test_init_writes_every_key_and_validates_once_inputs_are_filled(runner, tmp_path, method):
    out = tmp_path / "new.yaml"
    result = runner.invoke(cli, ["init", method, "--out", str(out)])
    assert result.exit_code == 0, result.stderr
    text = out.read_text()
    sample = next(p for p in sorted(CONFIGS.glob(f"{method}/*.yaml")))
    for line in text.splitlines():
        if "# REQUIRED" in line and not line.lstrip().startswith("#"):  # commented sections are examples
            assert line.split(": ", 1)[1].startswith("null  # REQUIRED: ")
    filled = "\n".join(
        line.replace("null  # REQUIRED", f'"{_any_input(sample)}"  # REQUIRED') for line in text.splitlines()
    )
    out.write_text(filled)
    result = runner.invoke(cli, ["validate", str(out)])
    assert result.exit_code == 0, result.stderr
    again = runner.invoke(cli, ["init", method, "--out", str(out)])
    assert again.exit_code == 2 and "file exists; init never replaces a file" in again.stderr
    assert out.read_text() == filled


def _any_input(sample_config: Path) -> Path:
    """An input file a bundled config names (any file will do for validation)."""
    from synthkit.runner import load_method_config

    _method, _cfg, inputs = load_method_config(sample_config)
    return inputs[0]


def test_init_lists_every_key_of_the_schema(runner):
    result = runner.invoke(cli, ["init", "retarget"])
    assert result.exit_code == 0
    for key in ("dense_radius: 0.02", "tau: 0.15", "max_cycles: 20", "input: null  # REQUIRED"):
        assert key in result.stdout
    assert "# Poisson-disk spacing of the dense support cloud; range > 0, <= 0.5" in result.stdout


@pytest.mark.parametrize("method", available_methods())
def test_schema_is_json_schema_of_the_config(runner, method):
    result = runner.invoke(cli, ["schema", method])
    assert result.exit_code == 0
    schema = json.loads(result.stdout)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert schema["additionalProperties"] is False and "seed" in schema["properties"]


@pytest.mark.parametrize("method", available_methods())
def test_set_example_in_help_is_a_real_key(runner, method):
    example = spec(method).set_example
    result = runner.invoke(cli, [method, "--help"])
    assert f"--set {example}" in " ".join(result.output.split())
    sample = sorted(CONFIGS.glob(f"{method}/*.yaml"))[0]
    assert runner.invoke(cli, ["validate", str(sample), "--set", example]).exit_code == 0
    assert "graphcut.max_cycles" not in result.output


# -- 5. one registry ------------------------------------------------------------------------------


def test_a_method_registered_once_gets_its_subcommand(runner, echo_method):
    result = runner.invoke(cli, ["--help"])
    assert result.exit_code == 0, result.stderr
    assert "  echo " in result.output
    result = runner.invoke(cli, ["echo", "--help"])
    assert result.exit_code == 0 and "A tiny method used only by the framework tests" in result.output


def test_symtex_stage_modules_do_not_import_the_pipeline():
    code = ("import sys, synthkit.methods.symtex.deform, synthkit.methods.symtex.common; "
            "print('synthkit.methods.symtex.pipeline' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


# ---- round 3 (issue 28): refused before the work, with the right reason


def _huge_png(path: Path, width: int, height: int) -> Path:
    """A PNG of a few hundred bytes whose header declares ``width`` x ``height`` pixels."""
    import struct
    import zlib

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\x00" * 64))
                     + chunk(b"IEND", b""))
    return path


def test_huge_image_input_refused_from_its_header(runner, tmp_path):
    """The PNG holds one row of pixels: only its header can have said 30000x30000."""
    png = _huge_png(tmp_path / "huge.png", 30000, 30000)
    cfg = tmp_path / "q.yaml"
    cfg.write_text(f"method: symmetry-texture\nmode: quilt\nsource: {png}\noutput_size: [64, 64]\n")
    before = snapshot(tmp_path)
    result = runner.invoke(cli, ["symmetry-texture", str(cfg), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert re.search(r"source: \S+huge.png \(30000x30000\) needs about 9e\+08 pixels \(limit ", one_error_line(result))
    assert snapshot(tmp_path) == before


def test_huge_image_refused_by_the_loader(tmp_path):
    from synthkit.errors import InputError
    from synthkit.io.images import load_image

    png = _huge_png(tmp_path / "t.png", 30000, 30000)
    with pytest.raises(InputError, match=r"t.png: image is 30000x30000 \(9e\+08 pixels\); images over 2.7e\+08"):
        load_image(png)


TWO_REGIONS = "regions: [{name: a, vertices: [0]}, {name: b, vertices: [1]}]\n"


def test_big_mesh_refused_from_its_header_under_max_memory(runner, tmp_path):
    ply = tmp_path / "big.ply"
    ply.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    b"property float z\nelement face 2000000\nproperty list uchar int vertex_indices\nend_header\n")
    cfg = tmp_path / "s.yaml"
    cfg.write_text(f"method: surface-by-numbers\ninput: {ply}\n{TWO_REGIONS}")
    result = runner.invoke(cli, ["--max-memory", "0.1", "surface-by-numbers", str(cfg), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert re.search(r"input: \S+big.ply \(2000000 faces\) needs about 2e\+06 faces \(limit ", one_error_line(result))


def test_config_file_too_large_refused_before_parsing(runner, tmp_path):
    cfg = tmp_path / "big.yaml"
    cfg.write_text("method: echo\nimage: in.png\n# " + "x" * (1 << 20) + "\n")
    result = runner.invoke(cli, ["validate", str(cfg)])
    assert result.exit_code == 2
    assert one_error_line(result) == (f"error: {cfg}: config file is 1.0 MiB; the limit is 1 MiB (large data such "
                                      "as strokes or labels belongs in the files a config names)")


@pytest.mark.slow
def test_config_with_too_many_values_has_its_own_reason(runner, tmp_path, echo_config):
    cfg = tmp_path / "many.yaml"
    values = ",".join(["1"] * (YAML_NODE_BUDGET + 1))
    cfg.write_text(f"method: echo\nimage: in.png\nextra: [{values}]\n")
    result = runner.invoke(cli, ["validate", str(cfg)])
    assert result.exit_code == 2
    assert f"config holds more than {YAML_NODE_BUDGET} YAML values" in one_error_line(result)


def test_sweeps_counted_before_expansion(runner, tmp_path, echo_config):
    result = runner.invoke(cli, ["run", str(echo_config), "--out-root", str(tmp_path / "o"), "--sweep", "seed=0..9999",
                                 "--sweep", "gain=1..1024", "--sweep", "filter.sigma=1..10"])
    assert result.exit_code == 2
    assert "the configs and sweeps make 102400000 runs; the limit is 100000" in one_error_line(result)


@pytest.mark.parametrize(("faces", "expected"), [
    ("f 1 1 2\nf 1 2 3\n", r"1 of 2 faces name one vertex twice \(first: face 0, vertices \[0, 0, 1\]\)"),
    ("f 1 2 4\n", r"every triangle has zero area \(1 faces\)"),
])
def test_self_looped_or_flat_meshes_refused_naming_the_file(runner, tmp_path, faces, expected):
    obj = tmp_path / "bad.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n" + faces)
    cfg = tmp_path / "s.yaml"
    cfg.write_text(f"method: surface-by-numbers\ninput: {obj}\n{TWO_REGIONS}")
    result = runner.invoke(cli, ["surface-by-numbers", str(cfg), "--out", str(tmp_path / "o")])
    assert result.exit_code == 3
    assert re.search(str(obj) + ": " + expected, one_error_line(result))


@pytest.mark.parametrize("method", available_methods())
def test_init_template_explains_every_null(runner, method):
    """A key written as null says why: REQUIRED, or what null means for it."""
    text = runner.invoke(cli, ["init", method]).stdout
    unexplained = [line.strip() for line in text.splitlines()
                   if not line.lstrip().startswith("#") and re.match(r"\s*[\w.]+: null\b", line)
                   and not re.search(r"REQUIRED|null|None|default|instead", line.split("#", 1)[-1])]
    assert unexplained == []
