"""Batches of runs: parameter sweeps, output folder names, and running the runs on Dask distributed.

The pure part (sweep parsing and expansion, folder names) has no dependencies. The Dask part
imports ``distributed`` only when called; :func:`dask_missing` tells whether it is installed
(the ``synthkit[dist]`` extra).

A run on a worker is :func:`execute`: it calls :func:`synthkit.runner.run_config` exactly as the
sequential ``synthkit run`` does and returns its outcome as a plain dict, so that an exception never
travels back through Dask. A worker that dies during a run is seen by the client as
``KilledWorker`` and is resubmitted up to ``retries`` times (:func:`run_on_dask`).
"""

from __future__ import annotations

import difflib
import hashlib
import itertools
import json
import math
import os
import re
import socket
import time
import traceback
import uuid
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

DIST_EXTRA = "synthkit[dist]"
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
"""Thread-count variables set to 1 in every local worker before it starts (no oversubscription)."""
MAX_NAME = 120
"""Longest output folder name from a sweep; longer names are cut and end with a hash of the whole."""
_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*(\.[A-Za-z0-9_-]+)*$")
_RANGE = re.compile(r"^(-?\d+)\.\.(-?\d+)$")
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


# ---------------------------------------------------------------------------------------- sweeps

def split_values(text: str) -> list[str]:
    """Split ``text`` at the commas that are not inside brackets, braces or quotes.

    >>> split_values("1,[2, 3],'a,b'")
    ['1', '[2, 3]', "'a,b'"]
    """
    parts, depth, quote, start = [], 0, None, 0
    for i, ch in enumerate(text):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return [p.strip() for p in parts]


def expand_values(values: Iterable[str]) -> list[str]:
    """Each value as written, with integer ranges ``a..b`` (both ends included) spelt out."""
    out: list[str] = []
    for value in values:
        match = _RANGE.match(value)
        if match:
            lo, hi = int(match.group(1)), int(match.group(2))
            if hi < lo:
                raise ValueError(f"range {value} is empty (write the smaller end first)")
            if hi - lo >= 10_000:
                raise ValueError(f"range {value} has more than 10000 values")
            out.extend(str(v) for v in range(lo, hi + 1))
        else:
            out.append(value)
    return out


def parse_sweep(text: str) -> tuple[str, list[str]]:
    """``"key.path=v1,v2,a..b"`` -> ``("key.path", ["v1", "v2", "a", ..., "b"])``.

    Values are YAML, as with ``--set``; each is kept as written (it names the folder). Raises
    ValueError with the reason.
    """
    key, sep, rest = text.partition("=")
    key = key.strip()
    if not sep or not _KEY.match(key):
        raise ValueError(f"{text!r} is not KEY.PATH=V1,V2,... (e.g. seed=0..9 or synth.patch=16,24)")
    values = split_values(rest)
    if any(v == "" for v in values):
        raise ValueError(f"{text!r} has an empty value")
    values = expand_values(values)
    if len(set(values)) != len(values):
        raise ValueError(f"{text!r} repeats a value")
    return key, values


def sweep_axes(specs: Iterable[str]) -> list[tuple[str, list[str]]]:
    """Parse every ``--sweep`` text; a key may be swept only once."""
    axes: list[tuple[str, list[str]]] = []
    for spec in specs:
        key, values = parse_sweep(spec)
        if any(key == k for k, _ in axes):
            raise ValueError(f"{key} is swept twice; give all its values in one --sweep")
        axes.append((key, values))
    return axes


MAX_BATCH_RUNS = 100_000
"""Most runs one ``synthkit run`` may plan (configs times sweep combinations); counted before any
combination is built."""


def config_method(path: str) -> str | None:
    """The ``method:`` a config file declares, or None when it cannot be read (the run reports why)."""
    from synthkit.config import load_yaml
    from synthkit.errors import SynthkitError

    try:
        method = load_yaml(Path(path)).get("method")
    except SynthkitError:
        return None
    return method if isinstance(method, str) else None


def axes_for(method: str | None, axes: Sequence[tuple[str, Sequence[str]]]):
    """Split sweep ``axes`` into those whose key ``method``'s schema has and those it lacks (a
    batch may mix methods: a sweep key applies where it means something). An unknown method keeps
    every axis, so that its run reports the problem."""
    from synthkit.config import schema_has_key
    from synthkit.methods import METHODS, config_module

    if method not in METHODS:
        return list(axes), []
    model = config_module(method).CONFIG
    kept = [(k, v) for k, v in axes if schema_has_key(model, k)]
    return kept, [k for k, _ in axes if not schema_has_key(model, k)]


def _folder_digest(folder: Path) -> str:
    """SHA-1 over the names and bytes of every file in ``folder`` but ``report.json``."""
    digest = hashlib.sha1()
    for path in sorted(p for p in folder.rglob("*") if p.is_file() and p.name != "report.json"):
        digest.update(path.relative_to(folder).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def seed_independent(rows: Sequence[dict]) -> list[str]:
    """The configs of a batch whose runs that differ only by a swept seed wrote byte-identical
    outputs (``report.json`` aside): their method's result does not depend on the seed."""
    groups: dict[tuple, list[dict]] = {}
    for row in rows:
        sweep = dict(row.get("sweep") or {})
        if "seed" in sweep and row.get("status") == "ok" and row.get("out"):
            sweep.pop("seed")
            groups.setdefault((row["config"], tuple(sorted(sweep.items()))), []).append(row)
    found = []
    for (config, _), members in groups.items():
        if len(members) > 1 and len({_folder_digest(Path(r["out"])) for r in members}) == 1 and config not in found:
            found.append(config)
    return found


def count_runs(axes: Sequence[tuple[str, Sequence[str]]]) -> int:
    """How many combinations :func:`combinations` yields (1 without axes)."""
    return math.prod(len(v) for _, v in axes)


def combinations(axes: Sequence[tuple[str, Sequence[str]]]) -> Iterator[dict[str, str]]:
    """The Cartesian product of the axes, lazily, the first axis varying slowest; one ``{}`` without axes."""
    keys = [k for k, _ in axes]
    return (dict(zip(keys, combo, strict=True)) for combo in itertools.product(*(v for _, v in axes)))


def sanitise(text: str) -> str:
    """``text`` with every run of characters outside ``[A-Za-z0-9._-]`` replaced by ``_``."""
    return _UNSAFE.sub("_", text).strip("_") or "_"


def folder_name(stem: str, sweep: dict[str, str]) -> str:
    """The output folder name of one sweep combination: ``stem__key-value__key-value``.

    >>> folder_name("facade", {"seed": "3", "analysis.dense_radius": "0.03"})
    'facade__seed-3__analysis.dense_radius-0.03'
    """
    name = stem + "".join(f"__{sanitise(k)}-{sanitise(v)}" for k, v in sweep.items())
    if len(name) > MAX_NAME:
        digest = hashlib.sha1(name.encode()).hexdigest()[:10]
        name = f"{name[: MAX_NAME - 11]}-{digest}"
    return name


def sweep_overrides(sweep: dict[str, str]) -> list[str]:
    """The ``--set`` overrides of one combination."""
    return [f"{k}={v}" for k, v in sweep.items()]


# ----------------------------------------------------------------------------------- batch files

BATCH_KEYS = ("configs", "set", "sweep")
"""Top-level keys of a batch file (a YAML file with ``configs:`` and no ``method:``)."""


@dataclass
class BatchFile:
    """A batch file: configs (paths relative to the file), ``set:`` overrides and ``sweep:`` axes."""

    path: str
    configs: list[str]
    overrides: list[str]
    axes: list[tuple[str, list[str]]]


def _yaml_text(value: Any) -> str:
    """``value`` as YAML text for an override: a string as written when it reads back as itself,
    anything else as JSON (which is YAML)."""
    import yaml

    if isinstance(value, str):
        try:
            if yaml.safe_load(value) == value:
                return value
        except yaml.YAMLError:
            pass
    return json.dumps(value)


def read_batch_file(path: str) -> BatchFile | None:
    """The batch file at ``path``, or None when ``path`` is not one (a config, or not readable:
    the run then reports that as for any config).

    A batch file is a YAML mapping with ``configs:`` (a list of config files, relative to the batch
    file) and no ``method:``; optional ``set:`` maps ``key.path`` to a value (as ``--set``) and
    ``sweep:`` maps ``key.path`` to a list of values or a range string ``"A..B"`` (as ``--sweep``).
    Raises ConfigError naming the file and the key for a malformed one.
    """
    from synthkit.config import load_yaml
    from synthkit.errors import ConfigError, SynthkitError

    try:
        data = load_yaml(Path(path))
    except SynthkitError:
        return None
    if "configs" not in data or "method" in data:
        return None
    unknown = sorted(set(data) - set(BATCH_KEYS))
    if unknown:
        close = difflib.get_close_matches(unknown[0], BATCH_KEYS, n=1)
        hint = f"did you mean {close[0]!r}?" if close else f"keys: {', '.join(BATCH_KEYS)}"
        raise ConfigError(f"{path}: unknown key {unknown[0]!r} in a batch file ({hint})")
    configs, overrides, sweep = data["configs"], data.get("set") or {}, data.get("sweep") or {}
    if not isinstance(configs, list) or not configs or not all(isinstance(c, str) and c for c in configs):
        raise ConfigError(f"{path}: configs: expected a list of config file paths")
    for key, value in (("set", overrides), ("sweep", sweep)):
        if not isinstance(value, dict) or not all(isinstance(k, str) and _KEY.match(k) for k in value):
            raise ConfigError(f"{path}: {key}: expected a mapping of key.path to values")
    axes = []
    for key, values in sweep.items():
        if isinstance(values, str):
            values = split_values(values)
        elif isinstance(values, list) and values:
            values = [v if isinstance(v, str) else _yaml_text(v) for v in values]  # strings as on the command line
        else:
            raise ConfigError(f"{path}: sweep.{key}: expected a list of values or a range such as 0..9")
        try:
            axes.append((key, expand_values(values)))
        except ValueError as exc:
            raise ConfigError(f"{path}: sweep.{key}: {exc}") from None
        if len(set(axes[-1][1])) != len(axes[-1][1]):
            raise ConfigError(f"{path}: sweep.{key}: repeats a value")
    base = Path(path).parent
    return BatchFile(path=str(path), configs=[str(base / c) if not os.path.isabs(c) else c for c in configs],
                     overrides=[f"{k}={_yaml_text(v)}" for k, v in overrides.items()], axes=axes)


# ------------------------------------------------------------------------------------------ jobs

@dataclass
class Job:
    """One run of a batch: a config, its overrides (batch file ``set:``, ``--set``, then the sweep's,
    all in ``overrides``; the first two also in ``set_overrides``) and its output folder."""

    config: str
    overrides: list[str]
    sweep: dict[str, str] = field(default_factory=dict)
    set_overrides: list[str] = field(default_factory=list)
    out: str | None = None


def worker_label() -> str:
    """``host:pid`` of this process, or the Dask worker's address when run in a worker."""
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def execute(config: str, out_dir: str, *, seed: int | None, overrides: Sequence[str], overwrite: bool,
            max_bytes: int | None, verbosity: int = 0, previews: str = "all",
            name_outputs: bool = False) -> dict[str, Any]:
    """Run one config into ``out_dir`` (on a worker) and return its outcome; never raises ``Exception``.

    Returns ``{"status", "exit_code", "error", "traceback", "seconds", "report", "worker"}``.
    """
    from synthkit.limits import Budget
    from synthkit.logs import configure_logging, describe_exception
    from synthkit.runner import run_config

    configure_logging(verbosity)
    start = time.perf_counter()
    outcome: dict[str, Any] = {"worker": worker_label(), "error": None, "traceback": None, "report": None}
    try:
        report = run_config(config, out_dir=out_dir, seed=seed, overrides=list(overrides), overwrite=overwrite,
                            show_progress=False, budget=Budget(max_bytes), previews=previews,
                            name_outputs=name_outputs)
    except Exception as exc:
        code, line = describe_exception(exc)
        outcome |= {"status": "failed", "exit_code": code, "error": line, "traceback": traceback.format_exc()}
    else:
        outcome |= {"status": "ok", "exit_code": 0, "report": report}
    outcome["seconds"] = round(time.perf_counter() - start, 3)
    return outcome


# ------------------------------------------------------------------------------------------ dask

def dask_missing() -> bool:
    """Whether Dask distributed (the ``synthkit[dist]`` extra) cannot be imported."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return True
    return False


class ClusterError(Exception):
    """The cluster cannot be used (no answer, no workers, a worker that cannot see the files): one line."""


def local_cluster(n_workers: int, *, retries_handled_by_client: bool = True):
    """A LocalCluster of ``n_workers`` single-threaded worker processes, threads limited to 1 each.

    The thread variables (:data:`THREAD_ENV`) are set in the environment the worker processes are
    spawned with, so they hold before numpy, BLAS or numba start. The scheduler does not reschedule a task whose worker
    died (``allowed-failures: 0``): :func:`run_on_dask` resubmits it itself, ``retries`` times.
    Worker memory is not limited by Dask (as in a sequential run; ``--max-memory`` budgets each run).
    """
    import logging

    import dask
    from distributed import LocalCluster

    # Dask's default pre-spawn environment also sets MALLOC_TRIM_THRESHOLD_=65536, which makes
    # glibc return memory to the system at every free: the bundled retarget analysis then runs twice
    # as slowly. A worker here gets the thread limits only, like a sequential run's memory behaviour.
    environ = {name: "1" for name in THREAD_ENV}
    settings = {
        "distributed.nanny.pre-spawn-environ": environ,
        "distributed.scheduler.worker-saturation": 1.0,
    }
    if retries_handled_by_client:
        settings["distributed.scheduler.allowed-failures"] = 0
    # The scheduler's HTTP server starts even without a dashboard, on port 8787 unless told
    # otherwise; a second batch on the same machine then warned "Port 8787 is already in use" (an
    # error under the tests' warning filter). ":0" lets the system pick a free port.
    with dask.config.set(settings):
        return LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, memory_limit=0,
                            dashboard_address=":0", silence_logs=logging.CRITICAL)


def read_scheduler_file(path: str) -> str:
    """The scheduler address written in a Dask scheduler file (JSON with ``address``)."""
    try:
        info = json.loads(Path(path).read_text())
        address = info["address"]
    except FileNotFoundError:
        raise ClusterError(f"--scheduler-file {path}: no such file") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else "not a Dask scheduler file (JSON with 'address')"
        raise ClusterError(f"--scheduler-file {path}: {reason}") from None
    if not isinstance(address, str) or not address:
        raise ClusterError(f"--scheduler-file {path}: not a Dask scheduler file (JSON with 'address')")
    return address


_ADDRESS = re.compile(r"^(?:(tcp|tls|ws|wss|ucx)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")


def check_address(address: str, *, what: str) -> None:
    """Refuse (ClusterError) what is not ``[PROTOCOL://]HOST:PORT`` with a port in 1..65535."""
    match = _ADDRESS.match(address)
    if not match or not 1 <= int(match.group(3)) <= 65535:
        raise ClusterError(f"{what}: not a scheduler address (tcp://HOST:PORT)")


def connect(address: str, *, timeout: float, what: str):
    """A Client of the scheduler at ``address`` with at least one worker, within ``timeout`` seconds.

    ``what`` names the option in the error line (``--scheduler tcp://...``)."""
    import logging

    from distributed import Client

    check_address(address, what=what)
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    start = time.monotonic()
    try:
        client = Client(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = f"no answer within {timeout:g} s" if isinstance(exc, OSError | TimeoutError) else str(exc)
        raise ClusterError(f"{what}: {reason}") from None
    left = max(timeout - (time.monotonic() - start), 1.0)
    try:
        client.wait_for_workers(1, timeout=left)
    except (TimeoutError, OSError):
        client.close()
        raise ClusterError(f"{what}: the scheduler has no workers (waited {timeout:g} s)") from None
    return client


def check_access(files: Sequence[str], out_root: str, probe: str) -> list[str]:
    """On a worker: the problems with reading ``files`` and writing into ``out_root`` (empty if none).

    ``probe`` is a file the client created in ``out_root``: a worker that does not see it is not on
    the client's filesystem."""
    problems = []
    for path in files:
        if not os.path.isfile(path):
            problems.append(f"cannot see {path}")
        elif not os.access(path, os.R_OK):
            problems.append(f"cannot read {path}")
    if not os.path.isfile(os.path.join(out_root, probe)):
        problems.append(f"does not see the --out-root {out_root} of this client (not a shared folder)")
    elif not os.access(out_root, os.W_OK | os.X_OK):
        problems.append(f"cannot write into --out-root {out_root}")
    return problems


def check_workers(client, files: Sequence[str], out_root: str) -> None:
    """Raise ClusterError naming the first worker that cannot read ``files`` or write ``out_root``."""
    root = Path(out_root).resolve()
    root.mkdir(parents=True, exist_ok=True)
    probe = f".synthkit-probe-{uuid.uuid4().hex}"
    (root / probe).write_text("probe\n")
    try:
        answers = client.run(check_access, list(files), str(root), probe)
    finally:
        (root / probe).unlink(missing_ok=True)
    for worker, problems in sorted(answers.items()):
        if problems:
            more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
            raise ClusterError(f"worker {worker} {problems[0]}{more}; inputs and --out-root must be on a "
                               "filesystem every worker shares")


def prepare_workers(client) -> None:
    """Register :class:`synthkit.batch_plugin.MainThreadImports` on every worker, present and future."""
    from synthkit.batch_plugin import MainThreadImports

    client.register_plugin(MainThreadImports())


class _Slots:
    """How many runs may be in flight: the workers' threads, asked of the scheduler at most every
    ``refresh`` seconds (workers may join or leave a cluster during a batch)."""

    def __init__(self, client, refresh: float = 5.0):
        self.client, self.refresh, self.asked, self.value = client, refresh, -float("inf"), 1

    def __call__(self) -> int:
        if time.monotonic() - self.asked > self.refresh:
            self.value = max(1, sum(self.client.nthreads().values()))
            self.asked = time.monotonic()
        return self.value


def _worker_of(client, future) -> str:
    """The address of the worker that last held ``future`` as the scheduler remembers it, or
    ``"unknown"`` when the scheduler no longer knows (the task is gone with its worker)."""
    try:
        who = client.who_has([future])
    except Exception:  # the scheduler may be gone too; the row still gets a worker field
        return "unknown"
    holders = who.get(future.key) or ()
    return str(next(iter(holders), "unknown"))


def run_on_dask(client, tasks: Sequence[dict[str, Any]], *, retries: int,
                on_done: Callable[[int, dict[str, Any]], None]) -> dict[str, float]:
    """Run :func:`execute` with each of ``tasks`` (its keyword arguments) on ``client``'s workers.

    At most as many runs are in flight as the workers have threads, so no run waits on a worker that
    might die under another. A run whose worker died is resubmitted up to ``retries`` times, then
    recorded failed. ``on_done(i, outcome)`` is called in the client as each run ends, with
    ``outcome["attempts"]`` and ``outcome["latency"]`` (seconds from submission to result in the
    client). Returns ``{"overhead": ...}``: the mean of latency minus the run's own seconds.
    """
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    token = uuid.uuid4().hex[:8]
    queue = list(range(len(tasks)))[::-1]
    meta: dict[str, tuple[int, int, float]] = {}
    done = as_completed(loop=client.loop)
    overheads: list[float] = []
    slots = _Slots(client)

    def submit(i: int, attempt: int) -> None:
        key = f"synthkit-run-{token}-{i}-{attempt}"
        meta[key] = (i, attempt, time.perf_counter())
        done.add(client.submit(execute, **tasks[i], key=key, pure=False))

    for _ in range(min(slots(), len(queue))):
        submit(queue.pop(), 0)
    for future in done:
        i, attempt, submitted = meta.pop(future.key)
        latency = time.perf_counter() - submitted
        if future.status == "finished":
            outcome = future.result()
            overheads.append(max(latency - outcome["seconds"], 0.0))
        else:
            exc = future.exception() if future.status == "error" else None
            worker = None
            if isinstance(exc, KilledWorker):
                if attempt < retries:
                    future.release()
                    submit(i, attempt + 1)
                    continue
                worker = getattr(getattr(exc, "last_worker", None), "address", None)
                line = (f"the worker running it died ({worker}); tried {attempt + 1} time"
                        f"{'s' if attempt else ''}" + ("" if retries else " (--retries resubmits it)"))
            elif exc is not None:
                line = f"internal error: {type(exc).__name__}: {exc}"
            else:
                line = f"the run was {future.status} by the cluster"
            outcome = {"status": "failed", "exit_code": 1, "error": line, "traceback": None, "report": None,
                       "seconds": round(latency, 3), "worker": worker or _worker_of(client, future),
                       "died": isinstance(exc, KilledWorker)}
        future.release()
        outcome |= {"attempts": attempt + 1, "latency": latency}
        on_done(i, outcome)
        if queue:
            for _ in range(min(slots() - len(meta), len(queue))):
                submit(queue.pop(), 0)
    return {"overhead": sum(overheads) / len(overheads) if overheads else 0.0}


__all__ = [
    "DIST_EXTRA",
    "BatchFile",
    "read_batch_file",
    "THREAD_ENV",
    "ClusterError",
    "check_address",
    "Job",
    "check_access",
    "check_workers",
    "combinations",
    "connect",
    "dask_missing",
    "execute",
    "folder_name",
    "local_cluster",
    "parse_sweep",
    "prepare_workers",
    "read_scheduler_file",
    "run_on_dask",
    "sanitise",
    "sweep_axes",
    "sweep_overrides",
]
