"""A run's context and its output folder: what a pipeline writes through (:class:`RunContext`),
the staging folder that becomes the output folder whole or not at all (:func:`staged_output`),
``report.json`` (:func:`write_report`), and the saving of a result computed in memory
(:func:`save_result`). Below the runner and the methods: it imports neither."""

from __future__ import annotations

import contextlib
import json
import logging
import shutil
import sys
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from synthkit import outdir
from synthkit.config import RunConfig
from synthkit.errors import SynthkitError, raise_if_terminated
from synthkit.io.atomic import write_text_atomic
from synthkit.limits import Budget
from synthkit.summary import summary_preview
from synthkit.version import __version__

log = logging.getLogger("synthkit")

PREVIEW_LEVELS = ("all", "summary", "none")
"""What ``--previews`` may say: every PNG preview, the one summary image of a run, or none."""


class RunContext:
    """What a pipeline gets besides its config: where to write, randomness, timing, progress.

    Attributes
    ----------
    out_dir : Path or None
        Staging folder; every output goes here (through :meth:`path`). None for a run in memory
        (:mod:`synthkit.api`), which writes nothing.
    seed : int
        The run's seed. ``rng`` is ``np.random.default_rng(seed)``; pass it down, never reseed.
    metrics : dict
        Filled by the pipeline; written to ``report.json`` under ``metrics``.
    timings : dict[str, float]
        Seconds per stage, accumulated by :meth:`stage`.
    outputs : dict[str, str]
        Output key -> file name relative to the output folder, registered by :meth:`path`.
    status : str
        ``report.json``'s ``status`` of a run that succeeds: ``"ok"``, ``"partial"`` when a method
        wrote a documented partial result (reshape's ``solver.allow_partial``), or ``"degraded"``
        when an output mesh is over one of its method's quality limits (:meth:`check_quality`).
    quality_warnings : list[str]
        The lines :meth:`check_quality` warned with (``--strict`` names the first).
    label : str
        What the stage line on a terminal starts with (``<method> <output folder name>``).
    name_outputs_as : str or None
        ``--name-outputs``: the run's name, under which its summary preview and main result are
        linked once the pipeline is done.
    previews : str
        ``"all"``, ``"summary"`` or ``"none"`` (``--previews``); ask :meth:`wants_preview`.
    strict : bool
        ``--strict``: a pipeline refuses (exit 2) what it would otherwise only warn about where it
        says so (surface-by-numbers: a painted colour that names no region); quality is judged by
        :func:`run_config`.
    budget : Budget
        The run's memory budget; call ``ctx.budget.require(key, value, count, unit, bytes_each=...)``
        with each size estimate before allocating (see :mod:`synthkit.limits`).
    """

    def __init__(
        self,
        out_dir: Path | None,
        *,
        seed: int,
        show_progress: bool = True,
        budget: Budget | None = None,
        previews: str = "all",
        strict: bool = False,
    ):
        self.out_dir = None if out_dir is None else Path(out_dir)
        self.strict = strict
        self.seed = int(seed)
        self.rng = np.random.default_rng(self.seed)
        self.show_progress = show_progress
        self.metrics: dict[str, Any] = {}
        self.timings: dict[str, float] = {}
        self.outputs: dict[str, str] = {}
        self.budget = budget if budget is not None else Budget()
        self.status = "ok"
        self.quality_warnings: list[str] = []
        self.label = "run"
        self.name_outputs_as: str | None = None
        if previews not in PREVIEW_LEVELS:
            raise ValueError(f"previews must be one of {', '.join(PREVIEW_LEVELS)}, got {previews!r}")
        self.previews = previews

    def wants_preview(self, level: str = "all") -> bool:
        """Whether to render a preview of ``level``: ``"summary"`` (the one image that shows a run's
        result, rendered unless previews are ``none``) or ``"all"`` (every other preview)."""
        if level not in ("summary", "all"):
            raise ValueError(f"preview level must be 'summary' or 'all', got {level!r}")
        return self.previews == "all" or (self.previews == "summary" and level == "summary")

    def preview_path(self, key: str, filename: str, level: str = "all") -> Path | None:
        """:meth:`path` for a preview of ``level`` the run keeps, else None (the preview functions of
        :mod:`synthkit.preview` then render without writing)."""
        return self.path(key, filename) if self.wants_preview(level) else None

    def check_quality(self, key: str, before: dict, after: dict, limits: dict) -> None:
        """Record the mesh-quality figures (:func:`synthkit.core.quality.mesh_quality`) of output
        ``key`` beside its input's in ``metrics["mesh_quality"][key]``, with the method's ``limits``
        (figure -> largest allowed value). Each figure over its limit is one warning line naming the
        figure and the limit, and makes the run ``degraded``."""
        self.metrics.setdefault("mesh_quality", {})[key] = {"input": before, "output": after, "limits": limits}
        for figure, limit in limits.items():
            value = after.get(figure)
            if value is not None and limit is not None and value > limit:
                line = f"{key}: {figure} {value} over its limit {limit} (input: {before.get(figure)})"
                log.warning("%s", line)
                self.quality_warnings.append(line)
                self.status = "degraded"

    @contextlib.contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the enclosed block; seconds are added to ``timings[name]``. On a terminal a stage
        that takes over 2 s says so on stderr (:class:`~synthkit.progress.StageTicker`). A SIGTERM
        that a library swallowed is raised again on entry and on a normal exit
        (:func:`raise_if_terminated`)."""
        from synthkit.progress import StageTicker

        raise_if_terminated()
        log.info("stage %s ...", name)
        start = time.perf_counter()
        ticker = (StageTicker(sys.stderr, f"{self.label}: {name}", busy=_bar_open)
                  if self._progress_on() else contextlib.nullcontext())
        try:
            with ticker:
                yield
            raise_if_terminated()
        finally:
            elapsed = time.perf_counter() - start
            self.timings[name] = self.timings.get(name, 0.0) + elapsed
            log.info("stage %s done in %.3f s", name, elapsed)

    def _progress_on(self) -> bool:
        return self.show_progress and sys.stderr.isatty()

    def progress(self, iterable: Iterable | None = None, *, total: int | None = None, desc: str = ""):
        """A tqdm progress bar on stderr, silent with --no-progress or when stderr is no TTY (the
        stage line of :meth:`stage` waits while a bar is open)."""
        from tqdm import tqdm

        return tqdm(iterable, total=total, desc=desc, file=sys.stderr, disable=not self._progress_on(), leave=False)

    def path(self, key: str, filename: str) -> Path:
        """Register output ``key`` as ``filename`` and return the path to write it to. An in-memory
        run (``out_dir`` None, :mod:`synthkit.api`) writes no files: asking for a path is a bug."""
        if self.out_dir is None:
            raise RuntimeError(f"in-memory run asked for output file {filename}; outputs are written by Result.save")
        if Path(filename).is_absolute() or ".." in Path(filename).parts:
            raise ValueError(f"output file name must be relative to the output folder: {filename}")
        self.outputs[key] = filename
        target = self.out_dir / filename
        target.parent.mkdir(parents=True, exist_ok=True)
        return target


def _bar_open() -> bool:
    """Whether a tqdm progress bar is on screen (tqdm tracks its open, enabled bars)."""
    from tqdm import tqdm

    return len(getattr(tqdm, "_instances", ())) > 0


@contextlib.contextmanager
def staged_output(out_dir: Path, protected: list[Path], *, overwrite: bool) -> Iterator[Path]:
    """Yield a staging folder for ``out_dir`` and move it into place when the block ends normally.

    ``protected`` are files the output folder may not hold or replace (the run's inputs and config).
    The folder is locked for the block (:func:`synthkit.outdir.target_lock`); any exception removes
    the staging folder, except a refusal that keeps its outputs (:class:`RefusalKept`), whose
    folder is moved into place before its error is raised.
    """
    target = outdir.check_target(out_dir, protected, overwrite=overwrite)
    target.parent.mkdir(parents=True, exist_ok=True)
    with outdir.target_lock(target):
        for leftover in outdir.remove_leftovers(target):
            log.info("removed %s, left by a run that is gone", leftover)
        outdir.check_target(out_dir, [], overwrite=overwrite)
        staging = outdir.staging_path(target)
        outdir.clear_staging(staging, target)
        try:
            outdir.make_staging(staging)
            try:
                yield staging
            except RefusalKept as kept:
                raise_if_terminated()
                outdir.move_into_place(staging, target, overwrite=overwrite)
                raise kept.error from None
            raise_if_terminated()
            outdir.move_into_place(staging, target, overwrite=overwrite)
        except BaseException:
            shutil.rmtree(staging, ignore_errors=True)
            raise


def save_result(result: Any, folder: Path | str, *, overwrite: bool = False, previews: str = "all") -> dict[str, Any]:
    """Write an in-memory run's ``result`` (a :class:`synthkit.api.Result`) into ``folder`` as the
    command line would: its output files and previews, ``report.json`` (with ``config_file: null``),
    atomically (:func:`staged_output`). The result's input files are protected as a run's are."""
    folder = Path(folder)
    with staged_output(folder, list(result.input_files), overwrite=overwrite) as staging:
        ctx = RunContext(staging, seed=result.config.seed, show_progress=False, previews=previews)
        ctx.label = f"{result.method} {folder.name}"
        ctx.metrics = dict(result.metrics)
        ctx.timings = {k: v for k, v in result.timings.items() if k != "total"}
        ctx.status = result.status
        ctx.quality_warnings = list(result.quality_warnings)
        start = time.perf_counter() - result.timings.get("total", 0.0)
        result.write(ctx)
        check_previews(result.method, ctx)
        report = write_report(result.method, result.config, ctx, None, start, ctx.status)
    return report


def check_previews(method: str, ctx: RunContext) -> None:
    """A run that keeps previews must have written a PNG (every method renders a summary image)."""
    if ctx.previews != "none" and not any(name.lower().endswith(".png") for name in ctx.outputs.values()):
        raise RuntimeError(f"method {method} wrote no PNG preview")


class RefusalKept(Exception):
    """A refusal whose staged outputs and report are complete: moved into place, then re-raised."""

    def __init__(self, error: SynthkitError):
        super().__init__(str(error))
        self.error = error


def write_report(
    method: str, cfg: RunConfig, ctx: RunContext, config_path: Path | None, start: float, status: str,
    error: str | None = None,
) -> dict[str, Any]:
    """Write ``report.json`` into the staging folder and return it."""
    ctx.timings["total"] = time.perf_counter() - start
    report = {
        "method": method,
        "version": __version__,
        "status": status,
        "seed": cfg.seed,
        "previews": ctx.previews,
        "config": cfg.model_dump(mode="json"),
        "config_file": None if config_path is None else str(Path(config_path).resolve()),
        "timings": ctx.timings,
        "metrics": ctx.metrics,
        "outputs": {**ctx.outputs, "report": "report.json"},
        "preview": summary_preview(ctx.outputs, method),
    }
    if error is not None:
        report["error"] = error
    report = _finite_or_none(to_jsonable(report))
    write_json(ctx.out_dir / "report.json", report)
    return report


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def to_jsonable(obj: Any) -> Any:
    """``obj`` with numpy scalars/arrays and paths turned into plain JSON values."""
    return json.loads(json.dumps(obj, default=_json_default, allow_nan=True))


def _finite_or_none(obj: Any) -> Any:
    """``obj`` with non-finite floats replaced by None (JSON has no NaN or infinity)."""
    if isinstance(obj, float):
        return obj if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite_or_none(v) for v in obj]
    return obj


def write_json(path: Path, obj: Any) -> None:
    """Write ``obj`` as indented JSON, atomically; numpy values become plain values and non-finite
    floats become null."""
    write_text_atomic(path, json.dumps(_finite_or_none(to_jsonable(obj)), indent=2, allow_nan=False) + "\n")


