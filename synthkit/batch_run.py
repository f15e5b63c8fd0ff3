"""Running a batch: planning its jobs, running them here or on Dask, and its report.

``synthkit run`` is a thin layer over this module: :func:`plan_jobs` turns configs, batch files
and sweeps into :class:`~synthkit.batch.Job` s (with the notes a user should read),
:func:`run_sequential` and :func:`run_distributed` fill a :class:`BatchReport` row by row, the
same way, and :meth:`BatchReport.finish` writes ``batch.json`` and the review page. The report
holds the batch semantics: row schema, statuses, the exit code and the summary lines.
"""

from __future__ import annotations

import json
import os
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from synthkit import batch
from synthkit.errors import ConfigError
from synthkit.logs import describe_exception
from synthkit.summary import headline, summary_preview

__all__ = ["BatchReport", "PlanError", "plan_jobs", "run_sequential", "run_distributed", "BATCH_FILE", "IN_PROCESS"]

BATCH_FILE = "batch.json"
IN_PROCESS = "in-process"
"""The ``worker`` of a row run by ``--workers 1`` in the ``synthkit run`` process itself."""


class PlanError(ValueError):
    """A batch that cannot be planned; ``option`` names the command-line option at fault (or None)."""

    def __init__(self, message: str, option: str | None = None):
        super().__init__(message)
        self.option = option


def _entries(configs: Sequence[str]) -> list[tuple[str, list[str], list]]:
    """(config, batch-file overrides, batch-file sweep axes) of every config, batch files expanded."""
    entries = []
    for path in configs:
        spec = batch.read_batch_file(path)  # ConfigError for a malformed batch file
        entries.extend([(c, spec.overrides, spec.axes) for c in spec.configs] if spec else [(path, [], [])])
    return entries


def plan_jobs(configs: Sequence[str], *, sweeps: Sequence[str], overrides: Sequence[str], seed: int | None,
              out_root: str) -> tuple[list[batch.Job], list[str]]:
    """The jobs of a batch and the notes to show (a sweep key a config's method lacks).

    Raises PlanError (a sweep given twice or with --seed, too many runs, clashing output names)
    or ConfigError (a malformed batch file)."""
    try:
        axes = batch.sweep_axes(sweeps)
    except ValueError as exc:
        raise PlanError(str(exc), "--sweep") from None
    entries = _entries(configs)
    for _, _, file_axes in entries:
        twice = sorted({k for k, _ in file_axes} & {k for k, _ in axes})
        if twice:
            raise PlanError(f"{twice[0]} is swept by a batch file too", "--sweep")
    if seed is not None and any(key == "seed" for _, _, a in entries for key, _ in [*a, *axes]):
        raise PlanError("--seed and --sweep seed=... both set the seed; give one", "--sweep")
    plans, notes = [], []
    for path, base, file_axes in entries:
        kept, dropped = batch.axes_for(batch.config_method(path), [*file_axes, *axes])
        if dropped:
            notes.append(f"note: {path} has no key {', '.join(dropped)}; it runs once for that sweep")
        plans.append((path, base, kept))
    planned = sum(batch.count_runs(kept) for _, _, kept in plans)
    if planned > batch.MAX_BATCH_RUNS:
        raise PlanError(f"the configs and sweeps make {planned} runs; the limit is {batch.MAX_BATCH_RUNS}", "--sweep")
    jobs = [batch.Job(path, [*base, *overrides, *batch.sweep_overrides(combo)], combo,
                      set_overrides=[*base, *overrides])
            for path, base, kept in plans for combo in batch.combinations(kept)]
    names = [batch.folder_name(Path(job.config).stem, job.sweep) for job in jobs]
    clashes = sorted({s for s in names if names.count(s) > 1})
    if clashes:
        raise PlanError(f"configs share output names under {out_root}: {', '.join(clashes)}")
    return jobs, notes


def out_dir_of(job: batch.Job, out_root: str) -> Path:
    """The output folder of ``job``: ``default_out_dir`` without a sweep, the sweep's name beside it."""
    from synthkit import outdir
    from synthkit.runner import default_out_dir

    if not job.sweep:
        return default_out_dir(job.config, out_root)
    target = Path(out_root) / batch.folder_name(outdir.output_name(job.config), job.sweep)
    if not outdir.inside(target, Path(out_root)):
        raise ConfigError(f"{job.config}: output folder {target} would lie outside {out_root}")
    return target


@dataclass
class BatchReport:
    """The rows of a batch, one per job, filled as runs end (``rows[i]`` is ``jobs[i]``'s)."""

    jobs: list
    out_root: Path
    strict: bool = False

    def __post_init__(self) -> None:
        self.out_root = Path(self.out_root)
        self.rows: list[dict] = [
            {"config": job.config, "overrides": list(job.set_overrides), "sweep": dict(job.sweep),
             "status": "skipped", "exit_code": None, "seconds": None, "out": None, "preview": None, "worker": None,
             "metrics": {}, "error": None} for job in self.jobs]

    def succeeded(self, i: int, report: dict, *, out: str, seconds: float, worker: str, attempts: int = 1) -> dict:
        """Row ``i`` of a run that wrote its outputs: ``ok``, or ``degraded`` (exit 3 when strict)."""
        row = self.rows[i] | {"status": "ok", "exit_code": 0, "seconds": seconds, "out": out, "worker": worker,
                              "metrics": headline(report.get("metrics", {})), "report": report}
        if attempts > 1:
            row["attempts"] = attempts
        if report.get("status") == "degraded":
            row |= {"status": "degraded", "exit_code": 3 if self.strict else 0,
                    "error": "output degraded" + (" (--strict)" if self.strict else "")}
        self.rows[i] = row
        return row

    def failed(self, i: int, code: int, line: str, *, seconds: float | None = None, worker: str | None = None,
               attempts: int = 1) -> dict:
        """Row ``i`` of a run that failed with exit ``code`` and the one-line ``line``."""
        row = self.rows[i] | {"status": "failed", "exit_code": code, "error": line, "seconds": seconds,
                              "worker": worker if worker is not None else self.rows[i]["worker"]}
        if attempts > 1:
            row["attempts"] = attempts
        self.rows[i] = row
        return row

    def failures(self) -> list[dict]:
        return [r for r in self.rows if r["status"] not in ("ok", "degraded") or r["exit_code"]]

    def exit_code(self) -> int:
        """The first failure's exit code, 0 when every run succeeded."""
        return next((r["exit_code"] for r in self.failures()), 0)

    def summary_lines(self) -> list[str]:
        """Notes on seed sweeps that changed nothing, the count line and one line per failure."""
        lines = [f"note: {config}: every seed gave the same result (this method does not depend on the seed here)"
                 for config in batch.seed_independent(self.rows)]
        failed = self.failures()
        lines.append(f"run: {len(self.rows) - len(failed)} succeeded, {len(failed)} failed")
        for r in failed:
            where = f" [{batch.folder_name(Path(r['config']).stem, r['sweep'])}]" if r["sweep"] else ""
            lines.append(f"  failed: {r['config']}{where} (exit {r['exit_code']}): {r['error']}")
        return lines

    def json_rows(self) -> list[dict]:
        """The rows with their full reports and an ``ok`` flag (``--json``)."""
        return [r | {"ok": r["status"] == "ok"} for r in self.rows]

    def finish(self) -> list[str]:
        """Give rows whose run left a folder their ``out`` and ``preview``, write ``batch.json`` and
        the review page; return the lines to show (a warning, or where the review page is)."""
        self._kept_folders()
        lines = self._write_batch()
        if any(r["out"] for r in self.rows) and self.out_root.is_dir():
            from synthkit.review import write_review

            try:
                lines.append(f"review: {write_review(self.out_root)}")
            except (OSError, ValueError) as exc:
                lines.append(f"warning: review page not written: {exc}")
        return lines

    def _kept_folders(self) -> None:
        for row, job in zip(self.rows, self.jobs, strict=True):
            out = row["out"] or job.out
            report = Path(out) / "report.json" if out else None
            if report is None or not report.is_file():
                continue
            try:
                outputs = json.loads(report.read_text()).get("outputs", {})
            except (OSError, ValueError):
                continue
            row |= {"out": out, "preview": summary_preview(outputs)}

    def _write_batch(self) -> list[str]:
        """Write ``batch.json`` (rows without full reports), unless a file of that name exists there
        that synthkit did not write (then a warning line is returned)."""
        from synthkit import __version__
        from synthkit.runner import write_json

        path = self.out_root / BATCH_FILE
        if path.exists():
            try:
                ours = "synthkit_batch" in json.loads(path.read_text())
            except (OSError, ValueError, TypeError):
                ours = False
            if not ours:
                return [f"warning: {path} exists and was not written by synthkit; batch.json not written"]
        self.out_root.mkdir(parents=True, exist_ok=True)
        write_json(path, {"synthkit_batch": __version__,
                          "runs": [{k: v for k, v in r.items() if k != "report"} for r in self.rows]})
        return []


OnDone = Callable[[int, dict, "BaseException | None", "str | None"], None]
"""Called as each run ends: ``(job index, its row, the exception or None, a traceback or None)``."""


def run_sequential(report: BatchReport, *, seed, overwrite: bool, show_progress: bool, budget, previews: str,
                   on_done: OnDone, name_outputs: bool = False) -> None:
    """Run every job of ``report`` in this process, one after another, filling its rows."""
    from synthkit.runner import run_config

    for i, job in enumerate(report.jobs):
        start = time.perf_counter()
        try:
            job.out = str(out_dir_of(job, str(report.out_root)))
            result = run_config(job.config, out_dir=job.out, seed=seed, overrides=job.overrides, overwrite=overwrite,
                                show_progress=show_progress, budget=budget, previews=previews,
                                name_outputs=name_outputs)
        except Exception as exc:
            code, line = describe_exception(exc)
            seconds = round(time.perf_counter() - start, 3)
            row = report.failed(i, code, line, seconds=seconds, worker=IN_PROCESS if job.out else None)
            on_done(i, row, exc, traceback.format_exc())
            continue
        row = report.succeeded(i, result, out=job.out, seconds=round(time.perf_counter() - start, 3),
                               worker=IN_PROCESS)
        on_done(i, row, None, None)


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


def _tasks(report: BatchReport, cluster: Cluster, *, seed, overwrite, max_bytes, verbosity, previews, on_done,
           name_outputs=False):
    """Validate every job here (same errors as a sequential run) and return (its task, the files it reads)."""
    from synthkit.runner import load_method_config

    tasks, files = {}, set()
    for i, job in enumerate(report.jobs):
        try:
            job.out = str(out_dir_of(job, str(report.out_root)))
            named: list[Path] = []
            _, _, inputs = load_method_config(Path(job.config), overrides=job.overrides, seed=seed, named_inputs=named)
        except Exception as exc:
            code, line = describe_exception(exc)
            on_done(i, report.failed(i, code, line), exc, traceback.format_exc())
            continue
        files.update(os.path.abspath(p) for p in [job.config, *named, *inputs])
        remote = cluster.remote
        tasks[i] = {"config": os.path.abspath(job.config) if remote else job.config,
                    "out_dir": os.path.abspath(job.out) if remote else job.out, "seed": seed,
                    "overrides": job.overrides, "overwrite": overwrite, "max_bytes": max_bytes,
                    "verbosity": verbosity, "previews": previews, "name_outputs": name_outputs}
    return tasks, files


def _client(cluster: Cluster, files, out_root):
    """(client, local cluster or None) ready to run; raises ClusterError with one line."""
    if cluster.remote:
        address = cluster.scheduler or batch.read_scheduler_file(cluster.scheduler_file)
        what = (f"--scheduler {cluster.scheduler}" if cluster.scheduler
                else f"--scheduler-file {cluster.scheduler_file} ({address})")
        client = batch.connect(address, timeout=cluster.timeout, what=what)
        try:
            batch.check_workers(client, sorted(files), out_root)
            batch.prepare_workers(client)
        except batch.ClusterError:
            client.close()
            raise
        return client, None
    from distributed import Client

    local = batch.local_cluster(cluster.workers)
    client = Client(local, set_as_default=False)
    try:
        batch.prepare_workers(client)
    except batch.ClusterError:
        client.close()
        local.close()
        raise
    return client, local


def run_distributed(report: BatchReport, cluster: Cluster, *, seed, overwrite: bool, max_bytes: int | None,
                    verbosity: int, previews: str, on_done: OnDone, name_outputs: bool = False) -> str | None:
    """Run the jobs of ``report`` on Dask, filling its rows; return None, or the one line saying why
    the cluster cannot be used (exit 2). Configs are validated here first."""
    from synthkit import outdir

    tasks, files = _tasks(report, cluster, seed=seed, overwrite=overwrite, max_bytes=max_bytes,
                          verbosity=verbosity, previews=previews, on_done=on_done, name_outputs=name_outputs)
    if not tasks:
        return None
    try:
        client, local = _client(cluster, files, report.out_root)
    except batch.ClusterError as exc:
        return str(exc)
    order = list(tasks)

    def done(k: int, outcome: dict) -> None:
        i = order[k]
        common = {"seconds": outcome["seconds"], "worker": outcome["worker"], "attempts": outcome.get("attempts", 1)}
        if outcome["status"] == "ok":
            on_done(i, report.succeeded(i, outcome["report"], out=report.jobs[i].out, **common), None, None)
            return
        row = report.failed(i, outcome["exit_code"], outcome["error"], **common)
        on_done(i, row, None, outcome.get("traceback"))
        if outcome.get("died"):
            outdir.remove_leftovers(Path(report.jobs[i].out).absolute())

    try:
        batch.run_on_dask(client, [tasks[i] for i in order], retries=cluster.retries, on_done=done)
    finally:
        client.close()
        if local is not None:
            local.close()  # interrupted: the workers are gone, so are their runs' staging folders
            for i in order:
                if report.rows[i]["status"] == "skipped":
                    outdir.remove_leftovers(Path(report.jobs[i].out).absolute())
    return None
