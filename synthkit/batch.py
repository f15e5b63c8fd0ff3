"""Running a batch: one run (:func:`execute`), the batch's rows and report, runs one after another.

``synthkit run`` plans its jobs with :mod:`synthkit.plan`, builds one
:class:`~synthkit.runner.RunSettings` and runs every job through :func:`execute`: in its own
process one after another (:func:`run_sequential`) or on Dask workers
(:func:`synthkit.cluster.run_distributed`). Each outcome becomes a row of :class:`BatchReport`
(:meth:`BatchReport.record`), which holds the batch semantics: row schema, statuses, the exit code,
the summary lines, ``batch.json`` and the review page.
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from synthkit.plan import Job, folder_name, out_dir_of
from synthkit.runner import RunSettings
from synthkit.summary import headline, summary_preview

BATCH_FILE = "batch.json"
IN_PROCESS = "in-process"
"""The ``worker`` of a row run by ``--workers 1`` in the ``synthkit run`` process itself."""


def worker_label() -> str:
    """``host:pid`` of this process, or the Dask worker's address when run in a worker."""
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def execute(job: Job, settings: RunSettings) -> dict[str, Any]:
    """Run ``job`` into ``job.out`` with ``settings`` and return its outcome; never raises ``Exception``.

    The one call of every batch run, sequential or on a Dask worker. A batch judges ``--strict``
    from its rows (:meth:`BatchReport.succeeded`: a degraded run exits 3), so the run itself is
    not strict. Returns ``{"status", "exit_code", "error", "traceback", "seconds", "report", "worker"}``.
    """
    from synthkit.logs import configure_logging, describe_exception
    from synthkit.runner import run_config

    configure_logging(settings.verbosity)
    start = time.perf_counter()
    outcome: dict[str, Any] = {"worker": worker_label(), "error": None, "traceback": None, "report": None}
    try:
        report = run_config(job.config, out_dir=job.out, overrides=list(job.overrides),
                            settings=replace(settings, strict=False))
    except Exception as exc:
        code, line = describe_exception(exc)
        outcome |= {"status": "failed", "exit_code": code, "error": line, "traceback": traceback.format_exc()}
    else:
        outcome |= {"status": "ok", "exit_code": 0, "report": report}
    outcome["seconds"] = round(time.perf_counter() - start, 3)
    return outcome


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
                              "metrics": headline(report.get("metrics", {}), report.get("method")), "report": report}
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

    def record(self, i: int, outcome: dict) -> dict:
        """Row ``i`` from the outcome of :func:`execute` (with the ``attempts`` a cluster made)."""
        common = {"seconds": outcome["seconds"], "worker": outcome["worker"], "attempts": outcome.get("attempts", 1)}
        if outcome["status"] == "ok":
            return self.succeeded(i, outcome["report"], out=self.jobs[i].out, **common)
        return self.failed(i, outcome["exit_code"], outcome["error"], **common)

    def failures(self) -> list[dict]:
        return [r for r in self.rows if r["status"] not in ("ok", "degraded") or r["exit_code"]]

    def exit_code(self) -> int:
        """The first failure's exit code, 0 when every run succeeded."""
        return next((r["exit_code"] for r in self.failures()), 0)

    def summary_lines(self) -> list[str]:
        """Notes on seed sweeps that changed nothing, the count line and one line per failure."""
        lines = [f"note: {config}: every seed gave the same result (this method does not depend on the seed here)"
                 for config in seed_independent(self.rows)]
        failed = self.failures()
        lines.append(f"run: {len(self.rows) - len(failed)} succeeded, {len(failed)} failed")
        for r in failed:
            where = f" [{folder_name(Path(r['config']).stem, r['sweep'])}]" if r["sweep"] else ""
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
                written = json.loads(report.read_text())
            except (OSError, ValueError):
                continue
            row |= {"out": out, "preview": summary_preview(written.get("outputs", {}), written.get("method"))}

    def _write_batch(self) -> list[str]:
        """Write ``batch.json`` (rows without full reports), unless a file of that name exists there
        that synthkit did not write (then a warning line is returned)."""
        from synthkit.context import write_json
        from synthkit.version import __version__

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


OnDone = Callable[[int, dict, "str | None"], None]
"""Called as each run ends: ``(job index, its row, its traceback or None)``."""


def run_sequential(report: BatchReport, settings: RunSettings, on_done: OnDone) -> None:
    """Run every job of ``report`` with ``settings`` in this process, one after another, filling its rows."""
    from synthkit.logs import describe_exception

    for i, job in enumerate(report.jobs):
        start = time.perf_counter()
        try:
            job.out = str(out_dir_of(job, str(report.out_root)))
        except Exception as exc:
            code, line = describe_exception(exc)
            on_done(i, report.failed(i, code, line, seconds=round(time.perf_counter() - start, 3)),
                    traceback.format_exc())
            continue
        outcome = execute(job, settings) | {"worker": IN_PROCESS}
        on_done(i, report.record(i, outcome), outcome["traceback"])


__all__ = ["BATCH_FILE", "IN_PROCESS", "BatchReport", "OnDone", "execute", "run_sequential", "seed_independent",
           "worker_label"]
