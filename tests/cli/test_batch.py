"""``synthkit run`` beyond one process: sweeps, a local Dask cluster, a cluster started by hand.

The cluster tests (marked slow) run the fastest bundled configs, one per method, so that the whole
file stays under about three minutes on the 2-core machine.
"""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from synthkit import batch, cluster, plan
from synthkit.cli.main import cli

REPO = Path(__file__).resolve().parents[2]
CONFIGS = REPO / "configs"
FAST = [
    CONFIGS / "symmetry-texture" / "quilt.yaml",
    CONFIGS / "symmetry-texture" / "symmetrize-lens.yaml",
    CONFIGS / "retarget" / "railing-analysis.yaml",
    CONFIGS / "petri-synth" / "building_ring.yaml",
]
CONNECT_TIMEOUT = 3.0
"""Seconds the unreachable-scheduler tests allow; the command must give up within this plus start-up."""

needs_dask = pytest.mark.skipif(cluster.dask_missing(), reason="needs synthkit[dist]")


# ------------------------------------------------------------------------------- pure helpers

def test_parse_sweep_values_ranges_and_yaml_lists():
    assert plan.parse_sweep("seed=0..3") == ("seed", ["0", "1", "2", "3"])
    assert plan.parse_sweep("synth.patch=16, 24,-2..-1") == ("synth.patch", ["16", "24", "-2", "-1"])
    assert plan.parse_sweep("output_size=[64, 64],[96,96]") == ("output_size", ["[64, 64]", "[96,96]"])
    assert plan.parse_sweep("name='a,b',c") == ("name", ["'a,b'", "c"])


@pytest.mark.parametrize("text, message", [
    ("seed", "is not KEY.PATH=V1,V2"),
    ("=1,2", "is not KEY.PATH=V1,V2"),
    ("a b=1", "is not KEY.PATH=V1,V2"),
    ("seed=1,,2", "has an empty value"),
    ("seed=3..1", "range 3..1 is empty"),
    ("seed=1,1", "repeats a value"),
    ("seed=0..100000", "more than 10000 values"),
])
def test_parse_sweep_errors(text, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        plan.parse_sweep(text)


def test_sweep_axes_refuse_a_key_twice_and_product_order():
    with pytest.raises(ValueError, match="seed is swept twice"):
        plan.sweep_axes(["seed=1,2", "seed=3"])
    axes = plan.sweep_axes(["seed=1..3", "gain=0.5,2"])
    combos = list(plan.combinations(axes))
    assert len(combos) == 6 == plan.count_runs(axes)
    assert combos[0] == {"seed": "1", "gain": "0.5"} and combos[1] == {"seed": "1", "gain": "2"}
    assert combos[-1] == {"seed": "3", "gain": "2"}
    assert list(plan.combinations([])) == [{}] and plan.count_runs([]) == 1


def test_folder_names_are_sanitised_and_bounded():
    name = plan.folder_name("facade", {"seed": "3", "analysis.dense_radius": "0.03"})
    assert name == "facade__seed-3__analysis.dense_radius-0.03"
    assert plan.folder_name("quilt", {"output_size": "[64, 64]"}) == "quilt__output_size-64_64"
    assert plan.folder_name("q", {"name": "'a/b c'"}) == "q__name-a_b_c"
    long = plan.folder_name("x", {"k": "v" * 300})
    assert len(long) == plan.MAX_NAME and re.fullmatch(r"[A-Za-z0-9._-]+", long)
    assert long != plan.folder_name("x", {"k": "v" * 301})


def test_check_access_names_what_a_worker_cannot_see(tmp_path):
    (tmp_path / "probe").write_text("")
    (tmp_path / "in.png").write_text("")
    assert cluster.check_access([str(tmp_path / "in.png")], str(tmp_path), "probe") == []
    problems = cluster.check_access([str(tmp_path / "gone.png")], str(tmp_path), "other-probe")
    assert problems[0] == f"cannot see {tmp_path / 'gone.png'}"
    assert "does not see the --out-root" in problems[1]


def test_read_scheduler_file_errors(tmp_path):
    with pytest.raises(cluster.ClusterError, match="no such file"):
        cluster.read_scheduler_file(str(tmp_path / "none.json"))
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(cluster.ClusterError, match="not a Dask scheduler file"):
        cluster.read_scheduler_file(str(bad))
    good = tmp_path / "good.json"
    good.write_text(json.dumps({"address": "tcp://10.0.0.1:8786", "type": "Scheduler"}))
    assert cluster.read_scheduler_file(str(good)) == "tcp://10.0.0.1:8786"


# ------------------------------------------------------------------- sweeps in this process

def test_sweep_in_process_3x2_folders_and_rows(runner, echo_config, tmp_path):
    root = tmp_path / "o"
    result = runner.invoke(cli, ["run", str(echo_config), "--out-root", str(root), "--sweep", "seed=1..3",
                                 "--sweep", "gain=0.5,2", "--set", "mode=copy"])
    assert result.exit_code == 0, result.stderr
    assert "run: 6 succeeded, 0 failed" in result.stderr
    names = sorted(p.name for p in root.iterdir() if p.is_dir() and p.name != "review")
    assert names == sorted(f"echo__seed-{s}__gain-{g}" for s in (1, 2, 3) for g in ("0.5", "2"))
    rows = json.loads((root / "batch.json").read_text())["runs"]
    assert [r["sweep"] for r in rows] == [{"seed": s, "gain": g} for s in "123" for g in ("0.5", "2")]
    for row in rows:
        assert row["status"] == "ok" and row["worker"] == "in-process" and row["overrides"] == ["mode=copy"]
        report = json.loads((Path(row["out"]) / "report.json").read_text())
        assert report["seed"] == int(row["sweep"]["seed"])
        assert report["config"]["gain"] == float(row["sweep"]["gain"])
        assert Path(row["out"]).name == plan.folder_name("echo", row["sweep"])


def test_sweep_failure_is_isolated(runner, echo_config, tmp_path):
    root = tmp_path / "o"
    result = runner.invoke(cli, ["run", str(echo_config), "--out-root", str(root), "--sweep", "gain=0,1"])
    assert result.exit_code == 2
    rows = json.loads((root / "batch.json").read_text())["runs"]
    assert [r["status"] for r in rows] == ["failed", "ok"]
    assert "gain: Input should be greater than 0" in rows[0]["error"]
    assert "failed: " in result.stderr and "[echo__gain-0]" in result.stderr
    assert not (root / "echo__gain-0").exists() and (root / "echo__gain-1" / "result.png").is_file()


def test_batch_file_with_set_and_sweep(runner, echo_config, tmp_path):
    sub = tmp_path / "study"
    sub.mkdir()
    (sub / "study.yaml").write_text(
        "configs: [../echo.yaml]\n"
        "set: {mode: copy}\n"
        "sweep:\n  gain: [0.5, 2]\n  seed: 1..3\n"
    )
    root = tmp_path / "o"
    result = runner.invoke(cli, ["run", str(sub / "study.yaml"), "--out-root", str(root), "--set", "filter.sigma=2"])
    assert result.exit_code == 0, result.stderr
    rows = json.loads((root / "batch.json").read_text())["runs"]
    assert len(rows) == 6 and rows[0]["config"] == str(sub / "../echo.yaml")
    assert rows[0]["overrides"] == ["mode=copy", "filter.sigma=2"]
    assert [Path(r["out"]).name for r in rows] == [f"echo__gain-{g}__seed-{s}" for g in ("0.5", "2") for s in "123"]
    report = json.loads((root / "echo__gain-2__seed-3" / "report.json").read_text())
    assert report["seed"] == 3 and report["config"]["gain"] == 2.0 and report["config"]["filter"]["sigma"] == 2.0


@pytest.mark.parametrize("text, message", [
    ("configs: [a.yaml]\nsweeps: {seed: 1..2}\n", "unknown key 'sweeps' in a batch file (did you mean 'sweep'?)"),
    ("configs: a.yaml\n", "configs: expected a list of config file paths"),
    ("configs: [a.yaml]\nsweep: {seed: 5}\n", "sweep.seed: expected a list of values or a range such as 0..9"),
    ("configs: [a.yaml]\nsweep: {seed: 3..1}\n", "sweep.seed: range 3..1 is empty (write the smaller end first)"),
    ("configs: [a.yaml]\nset: [seed]\n", "set: expected a mapping of key.path to values"),
])
def test_bad_batch_file_one_line_exit_2(runner, tmp_path, text, message):
    path = tmp_path / "b.yaml"
    path.write_text(text)
    result = runner.invoke(cli, ["run", str(path), "--out-root", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines() == [f"error: {path}: {message}"]


def test_sweep_key_in_batch_file_and_option_is_refused(runner, echo_config, tmp_path):
    path = tmp_path / "b.yaml"
    path.write_text("configs: [echo.yaml]\nsweep: {seed: 1..2}\n")
    result = runner.invoke(cli, ["run", str(path), "--sweep", "seed=3,4", "--out-root", str(tmp_path / "o")])
    assert result.exit_code == 2 and "seed is swept by a batch file too" in result.stderr


@pytest.mark.parametrize("args, message", [
    (["--sweep", "gain"], "--sweep"),
    (["--sweep", "seed=1,2", "--seed", "3"], "both set the seed"),
    (["--scheduler", "tcp://127.0.0.1:1", "--workers", "2"], "not both"),
    (["--scheduler", "tcp://127.0.0.1:1", "--scheduler-file", "x.json"], "not both"),
])
def test_batch_usage_errors_are_one_line_exit_2(echo_config, tmp_path, args, message):
    proc = subprocess.run([str(Path(sys.executable).parent / "synthkit"), "run", str(echo_config), "--out-root",
                           str(tmp_path / "o"), *args], capture_output=True, text=True, cwd=tmp_path, timeout=120,
                          env=_env())
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and message in proc.stderr, proc.stderr


@pytest.mark.parametrize("args", [["--workers", "2"], ["--scheduler", "tcp://127.0.0.1:1"]])
def test_without_dask_the_extra_is_named(runner, echo_config, tmp_path, monkeypatch, args):
    monkeypatch.setattr(cluster, "dask_missing", lambda: True)
    result = runner.invoke(cli, ["run", str(echo_config), "--out-root", str(tmp_path / "o"), *args])
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines() == [
        f"error: {args[0]}{' 2' if args[0] == '--workers' else ''} needs Dask distributed, which is not installed: "
        "pip install 'synthkit[dist]'"
    ]
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------------------- schedulers

def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    return env


@pytest.mark.parametrize("address", ["notanaddress", "inproc://x", "tcp://127.0.0.1:99999", "tcp://h:0", "tcp://:1"])
def test_scheduler_address_checked_before_connecting(address):
    with pytest.raises(cluster.ClusterError, match=re.escape(f"--scheduler {address}: not a scheduler address")):
        cluster.check_address(address, what=f"--scheduler {address}")


def test_scheduler_addresses_accepted():
    for address in ("tcp://127.0.0.1:8786", "node-3.cluster:8786", "tls://[::1]:8786", "ucx://10.0.0.2:13337"):
        cluster.check_address(address, what="--scheduler")


@needs_dask
def test_unreachable_scheduler_one_line_exit_2_within_timeout(runner, tmp_path):
    address = f"tcp://127.0.0.1:{_free_port()}"
    start = time.monotonic()
    result = runner.invoke(cli, ["run", str(FAST[0]), "--out-root", str(tmp_path / "o"), "--scheduler", address,
                                 "--connect-timeout", str(CONNECT_TIMEOUT)])
    elapsed = time.monotonic() - start
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines() == [f"error: --scheduler {address}: no answer within 3 s"]
    assert elapsed < CONNECT_TIMEOUT + 5
    assert not (tmp_path / "o" / "quilt").exists()


@needs_dask
def test_missing_scheduler_file_one_line_exit_2(runner, tmp_path):
    result = runner.invoke(cli, ["run", str(FAST[0]), "--out-root", str(tmp_path / "o"), "--scheduler-file",
                                 str(tmp_path / "sched.json")])
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines() == [f"error: --scheduler-file {tmp_path / 'sched.json'}: no such file"]


# ----------------------------------------------------------------------------- on a cluster

def _files(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` by relative path, without the marker (host and pid) and with the
    timings taken out of report.json."""
    out = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file() and path.name != ".synthkit-output":
            data = path.read_bytes()
            if path.name == "report.json":
                report = json.loads(data)
                report.pop("timings")
                data = json.dumps(report, sort_keys=True).encode()
            out[str(path.relative_to(folder))] = data
    return out


def _rows(root: Path) -> list[dict]:
    return json.loads((root / "batch.json").read_text())["runs"]


def _hidden(root: Path) -> list[str]:
    """Staging or old folders left beside the outputs (lock files are not folders)."""
    return sorted(p.name for p in root.iterdir() if p.name.startswith(".") and p.is_dir())


@needs_dask
@pytest.mark.slow
def test_local_cluster_same_bytes_as_sequential_and_failure_isolated(runner, tmp_path):
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(b"this is not a PNG file")
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"method: symmetry-texture\nmode: quilt\nsource: {garbage}\n")
    configs = [str(FAST[0]), str(bad), *map(str, FAST[1:])]
    seq, par = tmp_path / "seq", tmp_path / "par"
    first = runner.invoke(cli, ["run", *configs, "--out-root", str(seq), "--no-progress"])
    second = runner.invoke(cli, ["run", *configs, "--out-root", str(par), "--workers", "2", "--no-progress"])
    assert first.exit_code == second.exit_code == 3, (first.stderr, second.stderr)
    for result in (first, second):
        assert "run: 4 succeeded, 1 failed" in result.stderr
        assert f"failed: {bad} (exit 3)" in result.stderr
    rows_seq, rows_par = _rows(seq), _rows(par)
    assert [r["status"] for r in rows_par] == ["ok", "failed", "ok", "ok", "ok"]
    assert rows_par[1]["error"] == rows_seq[1]["error"] and str(garbage) in rows_par[1]["error"]
    workers = {r["worker"] for r in rows_par if r["status"] == "ok"}
    assert len(workers) == 2 and all(w.startswith("tcp://127.0.0.1:") for w in workers)
    assert {r["worker"] for r in rows_seq} == {"in-process"}
    for a, b in zip(rows_seq, rows_par, strict=True):
        same = ("config", "overrides", "sweep", "status", "exit_code", "metrics", "error")
        assert {k: a[k] for k in same} == {k: b[k] for k in same}
    for config in FAST:
        assert _files(seq / config.stem) == _files(par / config.stem), config
    assert not (par / "bad").exists() and _hidden(par) == []


@needs_dask
@pytest.mark.slow
def test_local_cluster_sweep_3x2(runner, tmp_path):
    root = tmp_path / "o"
    result = runner.invoke(cli, ["run", str(FAST[0]), "--out-root", str(root), "--workers", "2",
                                 "--sweep", "seed=1..3", "--sweep", "synth.patch=24,32"])
    assert result.exit_code == 0, result.stderr
    rows = _rows(root)
    assert [Path(r["out"]).name for r in rows] == [f"quilt__seed-{s}__synth.patch-{p}" for s in "123" for p in
                                                    ("24", "32")]
    for row in rows:
        report = json.loads((Path(row["out"]) / "report.json").read_text())
        assert report["seed"] == int(row["sweep"]["seed"])
        assert report["config"]["synth"]["patch"] == int(row["sweep"]["synth.patch"])
    images = {(Path(r["out"]) / "result.png").read_bytes() for r in rows}
    assert len(images) == 6


def _kill_first_run_of(root: Path, name: str, killed: list[int], stop: threading.Event) -> None:
    """Kill (SIGKILL) the worker process that stages ``name`` first; its pid is in the staging name."""
    while not stop.is_set() and not killed:
        for staging in root.glob(f".{name}.partial-*"):
            pid = int(staging.name.rsplit("-", 1)[1])
            if pid != os.getpid():
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                return
        time.sleep(0.01)


@needs_dask
@pytest.mark.slow
@pytest.mark.parametrize("retries", [0, 1])
def test_worker_killed_during_a_run(runner, tmp_path, retries):
    root = tmp_path / "o"
    root.mkdir()
    victim = FAST[3]  # building_ring, the longest of the four
    killed: list[int] = []
    stop = threading.Event()
    watcher = threading.Thread(target=_kill_first_run_of, args=(root, victim.stem, killed, stop), daemon=True)
    watcher.start()
    try:
        result = runner.invoke(cli, ["run", str(victim), str(FAST[0]), str(FAST[1]), "--out-root", str(root),
                                     "--workers", "2", "--retries", str(retries), "--no-progress"])
    finally:
        stop.set()
        watcher.join()
    assert len(killed) == 1
    rows = _rows(root)
    assert [r["status"] for r in rows[1:]] == ["ok", "ok"]
    if retries:
        assert result.exit_code == 0, result.stderr
        assert rows[0]["status"] == "ok" and rows[0]["attempts"] == 2
        assert (root / victim.stem / "report.json").is_file()
    else:
        assert result.exit_code == 1
        assert rows[0]["status"] == "failed" and "worker running it died" in rows[0]["error"]
        assert rows[0]["worker"].startswith("tcp://") and rows[0]["worker"] in rows[0]["error"]
        assert "--retries resubmits it" in result.stderr
        assert not (root / victim.stem).exists()
    assert _hidden(root) == []


@needs_dask
@pytest.mark.slow
def test_cluster_started_by_hand(runner, tmp_path):
    """``dask scheduler`` and ``dask worker`` subprocesses on a free port, found by a scheduler file."""
    sched_file = tmp_path / "scheduler.json"
    port = _free_port()
    env = _env()
    procs = [subprocess.Popen([sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard", "--scheduler-file", str(sched_file)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        procs.append(subprocess.Popen([sys.executable, "-m", "dask", "worker", "--scheduler-file", str(sched_file),
                                       "--nworkers", "1", "--nthreads", "1", "--no-dashboard"], env=env,
                                      cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        deadline = time.monotonic() + 60
        while not sched_file.is_file() and time.monotonic() < deadline:
            time.sleep(0.1)
        root = tmp_path / "o"
        result = runner.invoke(cli, ["run", str(FAST[0]), str(FAST[1]), "--out-root", str(root), "--scheduler-file",
                                     str(sched_file), "--connect-timeout", "60", "--no-progress"])
        assert result.exit_code == 0, result.stderr
        rows = _rows(root)
        assert [r["status"] for r in rows] == ["ok", "ok"]
        assert len({r["worker"] for r in rows}) == 1 and rows[0]["worker"].startswith("tcp://")
        result = runner.invoke(cli, ["run", str(FAST[0]), "--out-root", str(root), "--scheduler",
                                     f"tcp://127.0.0.1:{port}", "--overwrite", "--no-progress"])
        assert result.exit_code == 0, result.stderr
        assert (root / "quilt" / "result.png").is_file()
    finally:
        for proc in reversed(procs):
            proc.terminate()
        for proc in reversed(procs):
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


@needs_dask
@pytest.mark.slow
def test_local_workers_thread_limits_and_main_thread_imports():
    """Workers start with the thread limits and without Dask's MALLOC_TRIM_THRESHOLD_, and import
    pymeshlab in their main thread (imported first in a task thread, it aborts the worker at exit)."""
    from distributed import Client

    def worker_state() -> dict:  # local, so that it is pickled by value: workers cannot import tests/
        import os
        import sys
        import threading

        from synthkit import cluster

        return {"pymeshlab": "pymeshlab" in sys.modules, "threads": {k: os.environ.get(k) for k in cluster.THREAD_ENV},
                "malloc_trim": os.environ.get("MALLOC_TRIM_THRESHOLD_"), "main": threading.current_thread().name}

    local = cluster.local_cluster(1)
    try:
        with Client(local, set_as_default=False) as client:
            cluster.prepare_workers(client)
            (state,) = client.run(worker_state).values()
    finally:
        local.close()
    assert state == {"pymeshlab": True, "threads": dict.fromkeys(cluster.THREAD_ENV, "1"), "malloc_trim": None,
                     "main": "MainThread"}


@needs_dask
@pytest.mark.slow
def test_two_local_clusters_on_one_machine_start_without_a_port_warning():
    """The scheduler's HTTP server took port 8787 even without a dashboard, so a second batch on
    the machine warned "Port 8787 is already in use" (an error under this suite's filter: a CI
    run beside another batch failed). Each now binds a port of its own."""
    first = cluster.local_cluster(1)
    try:
        second = cluster.local_cluster(1)
        try:
            ports = {first.scheduler.http_server.port, second.scheduler.http_server.port}
        finally:
            second.close()
    finally:
        first.close()
    assert len(ports) == 2 and 8787 not in ports


@needs_dask
@pytest.mark.slow
def test_sigterm_during_a_local_cluster_batch_leaves_no_half_folder(tmp_path):
    root = tmp_path / "o"
    root.mkdir()
    proc = subprocess.Popen([str(Path(sys.executable).parent / "synthkit"), "run", str(FAST[3]), str(FAST[2]),
                             "--out-root", str(root), "--workers", "2", "--no-progress"], env=_env(), cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not list(root.glob(".*.partial-*")) and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.01)
        proc.send_signal(signal.SIGTERM)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 143, stderr
    assert "error: terminated (SIGTERM)" in stderr
    assert _hidden(root) == []
    for row in _rows(root):
        folder = root / Path(row["config"]).stem
        assert row["status"] in ("ok", "skipped")
        # a run may finish on its worker after the client stopped listening: skipped, yet complete
        assert (folder / "report.json").is_file() and (folder / ".synthkit-output").is_file() or (
            row["status"] == "skipped" and not folder.exists())


def test_a_seed_sweep_that_changes_nothing_is_named_once(tmp_path):
    rows = []
    for seed, content in (("0", b"same"), ("1", b"same"), ("2", b"same")):
        out = tmp_path / f"a{seed}"
        out.mkdir()
        (out / "result.bin").write_bytes(content)
        (out / "report.json").write_text(seed)  # reports differ (seed, timings): not compared
        rows.append({"config": "a.yaml", "sweep": {"seed": seed}, "status": "ok", "out": str(out)})
    for seed in ("0", "1"):
        out = tmp_path / f"b{seed}"
        out.mkdir()
        (out / "result.bin").write_bytes(seed.encode())
        rows.append({"config": "b.yaml", "sweep": {"seed": seed}, "status": "ok", "out": str(out)})
    assert batch.seed_independent(rows) == ["a.yaml"]
