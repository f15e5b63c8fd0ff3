"""Running a batch's jobs on Dask distributed: a local cluster or an existing scheduler.

Dask is imported only when called; :func:`dask_missing` tells whether it is installed (the
``synthkit[dist]`` extra). Each run on a worker is :func:`synthkit.batch.execute`, the same call a
sequential batch makes, which returns its outcome as a plain dict, so that an exception never
travels back through Dask. A worker that dies during a run is seen by the client as
``KilledWorker`` and is resubmitted up to ``retries`` times (:func:`run_on_dask`).
"""

from __future__ import annotations

import json
import os
import re
import time
import traceback
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from synthkit.batch import BatchReport, OnDone, execute
from synthkit.plan import Job, out_dir_of
from synthkit.runner import RunSettings

DIST_EXTRA = "synthkit[dist]"
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
"""Thread-count variables set to 1 in every local worker before it starts (no oversubscription)."""


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
    """Register :class:`synthkit.cluster_plugin.MainThreadImports` on every worker, present and future."""
    from synthkit.cluster_plugin import MainThreadImports

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


def run_on_dask(client, tasks: Sequence[tuple[Job, RunSettings]], *, retries: int,
                on_done: Callable[[int, dict[str, Any]], None]) -> dict[str, float]:
    """Run :func:`synthkit.batch.execute` with each of ``tasks`` (a job and its settings) on
    ``client``'s workers.

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
        done.add(client.submit(execute, *tasks[i], key=key, pure=False))

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




@dataclass
class Cluster:
    """Where Dask runs go: ``workers`` local processes, or an existing scheduler's address or file."""

    workers: int = 1
    scheduler: str | None = None
    scheduler_file: str | None = None
    timeout: float = 10.0
    retries: int = 0

    @property
    def remote(self) -> bool:
        return bool(self.scheduler or self.scheduler_file)


def _tasks(report: BatchReport, cluster: Cluster, settings: RunSettings, on_done: OnDone):
    """Validate every job here (same errors as a sequential run); return ``{job index: (job, settings)}``
    as a worker runs them (absolute paths for a remote cluster, no progress bars) and the files they read."""
    from synthkit.logs import describe_exception
    from synthkit.runner import load_method_config

    tasks, files = {}, set()
    worker_settings = replace(settings, show_progress=False)
    for i, job in enumerate(report.jobs):
        try:
            job.out = str(out_dir_of(job, str(report.out_root)))
            named: list[Path] = []
            _, _, inputs = load_method_config(Path(job.config), overrides=job.overrides, seed=settings.seed,
                                              named_inputs=named)
        except Exception as exc:
            code, line = describe_exception(exc)
            on_done(i, report.failed(i, code, line), traceback.format_exc())
            continue
        files.update(os.path.abspath(p) for p in [job.config, *named, *inputs])
        if cluster.remote:
            job = replace(job, config=os.path.abspath(job.config), out=os.path.abspath(job.out))
        tasks[i] = (job, worker_settings)
    return tasks, files


def _client(cluster: Cluster, files, out_root):
    """(client, local cluster or None) ready to run; raises ClusterError with one line."""
    if cluster.remote:
        address = cluster.scheduler or read_scheduler_file(cluster.scheduler_file)
        what = (f"--scheduler {cluster.scheduler}" if cluster.scheduler
                else f"--scheduler-file {cluster.scheduler_file} ({address})")
        client = connect(address, timeout=cluster.timeout, what=what)
        try:
            check_workers(client, sorted(files), out_root)
            prepare_workers(client)
        except ClusterError:
            client.close()
            raise
        return client, None
    from distributed import Client

    local = local_cluster(cluster.workers)
    client = Client(local, set_as_default=False)
    try:
        prepare_workers(client)
    except ClusterError:
        client.close()
        local.close()
        raise
    return client, local


def run_distributed(report: BatchReport, cluster: Cluster, settings: RunSettings, on_done: OnDone) -> str | None:
    """Run the jobs of ``report`` with ``settings`` on Dask, filling its rows; return None, or the
    one line saying why the cluster cannot be used (exit 2). Configs are validated here first."""
    from synthkit import outdir

    tasks, files = _tasks(report, cluster, settings, on_done)
    if not tasks:
        return None
    try:
        client, local = _client(cluster, files, report.out_root)
    except ClusterError as exc:
        return str(exc)
    order = list(tasks)

    def done(k: int, outcome: dict) -> None:
        i = order[k]
        on_done(i, report.record(i, outcome), outcome.get("traceback"))
        if outcome.get("died"):
            outdir.remove_leftovers(Path(report.jobs[i].out).absolute())

    try:
        run_on_dask(client, [tasks[i] for i in order], retries=cluster.retries, on_done=done)
    finally:
        client.close()
        if local is not None:
            local.close()  # interrupted: the workers are gone, so are their runs' staging folders
            for i in order:
                if report.rows[i]["status"] == "skipped":
                    outdir.remove_leftovers(Path(report.jobs[i].out).absolute())
    return None


__all__ = ["DIST_EXTRA", "THREAD_ENV", "Cluster", "ClusterError", "check_access", "check_address", "check_workers",
           "connect", "dask_missing", "local_cluster", "prepare_workers", "read_scheduler_file", "run_distributed",
           "run_on_dask"]
