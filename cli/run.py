"""``synthkit run CONFIG...``: run many configs, each by its ``method:`` key, for batch jobs.

In this process one after another (``--workers 1``, the default), on a local Dask cluster
(``--workers N``) or on an existing one (``--scheduler`` / ``--scheduler-file``); ``--sweep`` turns
each config into the Cartesian product of the swept values (:mod:`synthkit.plan`).
"""

from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

import click

from .options import (
    global_options,
    json_option,
    name_outputs_option,
    overwrite_option,
    previews_option,
    print_summary,
    progress_option,
    run_settings,
    seed_option,
    set_option,
    strict_mode,
    verbosity,
)


@click.command(name="run")
@click.argument("configs", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=str))
@click.option("--out-root", type=click.Path(file_okay=False, path_type=str), default="out", show_default=True,
              help="Each config writes into OUT_ROOT/<config file name without suffix>; batch.json goes here.")
@seed_option
@set_option
@click.option("--sweep", "sweeps", multiple=True, metavar="KEY.PATH=V1,V2,...",
              help="Run every config once per value (repeatable: the Cartesian product); integer ranges "
                   "as A..B, e.g. --sweep seed=0..9. Folders are named <config>__KEY-VALUE...")
@click.option("--workers", type=click.IntRange(1, 1024), default=1, show_default=True,
              help="Runs at once, on a local Dask cluster of this many single-threaded worker processes "
                   "(1: one after another in this process). Needs synthkit[dist].")
@click.option("--scheduler", metavar="tcp://HOST:PORT", default=None,
              help="Run on the Dask cluster of this scheduler; inputs and --out-root must be on a filesystem "
                   "its workers share. Needs synthkit[dist].")
@click.option("--scheduler-file", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Like --scheduler, with the address read from a Dask scheduler file (dask-jobqueue, dask-mpi).")
@click.option("--connect-timeout", type=click.FloatRange(0.1, 3600), default=10.0, show_default=True,
              metavar="SECONDS", help="How long to wait for the scheduler to answer and to have a worker.")
@click.option("--retries", type=click.IntRange(0, 100), default=0, show_default=True,
              help="Resubmit a run whose worker died (killed, out of memory) up to this many times.")
@overwrite_option
@progress_option
@previews_option
@json_option
@name_outputs_option
@global_options
@click.pass_context
def command(ctx, configs, out_root, seed, overrides, sweeps, workers, scheduler, scheduler_file, connect_timeout,
            retries, overwrite, no_progress, previews, as_json, name_outputs) -> None:
    """Run every CONFIG, dispatching on its `method:` key.

    A failed config is reported and the batch goes on; at the end every failure is listed, the
    rows are written to OUT_ROOT/batch.json, and the command exits with the exit code of the first
    failure (0 when all succeeded).
    """
    from synthkit import batch, cluster, plan
    from synthkit.errors import ConfigError

    if scheduler and scheduler_file:
        raise click.UsageError("give --scheduler or --scheduler-file, not both")
    where = cluster.Cluster(workers, scheduler, scheduler_file, connect_timeout, retries)
    if where.remote and workers > 1:
        raise click.UsageError("--workers starts a local cluster; give it or --scheduler, not both")
    try:
        jobs, notes = plan.plan_jobs(configs, sweeps=sweeps, overrides=overrides, seed=seed, out_root=out_root)
    except plan.PlanError as exc:
        if exc.option:
            raise click.BadParameter(str(exc), param_hint=exc.option) from None
        _fail(ctx, str(exc))
    except ConfigError as exc:
        _fail(ctx, str(exc))
    if (where.remote or workers > 1) and cluster.dask_missing():
        option = f"--workers {workers}" if workers > 1 else ("--scheduler" if scheduler else "--scheduler-file")
        _fail(ctx, f"{option} needs Dask distributed, which is not installed: pip install '{cluster.DIST_EXTRA}'")
    _say(ctx, notes)
    report = batch.BatchReport(jobs, Path(out_root), strict=strict_mode(ctx))
    settings = run_settings(ctx, seed=seed, overwrite=overwrite, no_progress=no_progress, previews=previews,
                            name_outputs=name_outputs)
    bar = _progress_bar(ctx, len(jobs), no_progress)
    on_done = _printer(ctx, bar)
    problem = None
    try:
        if where.remote or workers > 1:
            problem = cluster.run_distributed(report, where, settings, on_done)
        else:
            batch.run_sequential(report, settings, on_done)
    finally:
        bar.close()
        _say(ctx, report.finish(), always=True)
    if problem:
        _fail(ctx, problem)
    if as_json:
        click.echo(json.dumps(report.json_rows(), indent=2))
    _say(ctx, report.summary_lines())
    ctx.exit(report.exit_code())


def _fail(ctx, line: str) -> None:
    click.echo(f"error: {line}", err=True)
    ctx.exit(2)


def _say(ctx, lines: list[str], *, always: bool = False) -> None:
    """Print ``lines`` on stderr (unless -q; warnings always when ``always``)."""
    for line in lines:
        if verbosity(ctx) >= 0 or (always and line.startswith("warning:")):
            click.echo(line, err=True)


def _printer(ctx, bar):
    """The callback printing each run's outcome above the progress bar: its summary, or its error
    line (with the traceback under -v)."""

    def on_done(i: int, row: dict, trace) -> None:
        with _above(bar):
            if row["status"] in ("ok", "degraded"):
                print_summary(ctx, row["report"], row["out"])
            else:
                if trace and verbosity(ctx) > 0:
                    click.echo(trace.rstrip(), err=True)
                line, path = row["error"], row["config"]
                click.echo(f"error: {path}: {line}" if not line.startswith(str(path)) else f"error: {line}", err=True)
        bar.update()

    return on_done


def _progress_bar(ctx, total: int, no_progress: bool):
    """A tqdm bar over the runs on stderr; silent with --no-progress, -q or when stderr is no TTY."""
    from tqdm import tqdm

    enabled = not no_progress and verbosity(ctx) >= 0 and sys.stderr.isatty() and total > 1
    return tqdm(total=total, desc="runs", unit="run", file=sys.stderr, disable=not enabled, position=0)


@contextlib.contextmanager
def _above(bar):
    """Print lines above the progress bar (the bar is cleared and redrawn)."""
    if bar.disable:
        yield
        return
    with bar.external_write_mode(file=sys.stderr):
        yield
