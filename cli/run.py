"""``synthkit run CONFIG...``: run many configs, each by its ``method:`` key, for batch jobs.

In this process one after another (``--workers 1``, the default), on a local Dask cluster
(``--workers N``) or on an existing one (``--scheduler`` / ``--scheduler-file``); ``--sweep`` turns
each config into the Cartesian product of the swept values (:mod:`synthkit.batch`).
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
import traceback
from pathlib import Path

import click

from .options import (
    HEADLINE_METRICS,
    describe_exception,
    json_option,
    overwrite_option,
    previews_option,
    print_summary,
    progress_option,
    run_budget,
    seed_option,
    set_option,
    strict_mode,
    verbosity,
)

BATCH_FILE = "batch.json"
IN_PROCESS = "in-process"
"""The ``worker`` of a row run by ``--workers 1`` in the ``synthkit run`` process itself."""


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
@click.pass_context
def command(ctx, configs, out_root, seed, overrides, sweeps, workers, scheduler, scheduler_file, connect_timeout,
            retries, overwrite, no_progress, previews, as_json) -> None:
    """Run every CONFIG, dispatching on its `method:` key.

    A failed config is reported and the batch goes on; at the end every failure is listed, the
    rows are written to OUT_ROOT/batch.json, and the command exits with the exit code of the first
    failure (0 when all succeeded).
    """
    from synthkit import batch
    from synthkit.errors import ConfigError

    try:
        axes = batch.sweep_axes(sweeps)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--sweep") from None
    entries = []  # (config, overrides before --set, sweep axes before --sweep)
    for path in configs:
        try:
            spec = batch.read_batch_file(path)
        except ConfigError as exc:
            click.echo(f"error: {exc}", err=True)
            ctx.exit(2)
        entries.extend([(c, spec.overrides, spec.axes) for c in spec.configs] if spec else [(path, [], [])])
    for _, _, file_axes in entries:
        twice = sorted({k for k, _ in file_axes} & {k for k, _ in axes})
        if twice:
            raise click.BadParameter(f"{twice[0]} is swept by a batch file too", param_hint="--sweep")
    if seed is not None and any(key == "seed" for _, _, a in entries for key, _ in [*a, *axes]):
        raise click.BadParameter("--seed and --sweep seed=... both set the seed; give one", param_hint="--sweep")
    if scheduler and scheduler_file:
        raise click.UsageError("give --scheduler or --scheduler-file, not both")
    remote = scheduler or scheduler_file
    if remote and workers > 1:
        raise click.UsageError("--workers starts a local cluster; give it or --scheduler, not both")
    if (remote or workers > 1) and batch.dask_missing():
        option = f"--workers {workers}" if workers > 1 else ("--scheduler" if scheduler else "--scheduler-file")
        click.echo(f"error: {option} needs Dask distributed, which is not installed: "
                   f"pip install '{batch.DIST_EXTRA}'", err=True)
        ctx.exit(2)

    jobs = [batch.Job(path, [*base, *overrides, *batch.sweep_overrides(combo)], combo,
                      set_overrides=[*base, *overrides])
            for path, base, file_axes in entries for combo in batch.combinations([*file_axes, *axes])]
    names = [batch.folder_name(Path(job.config).stem, job.sweep) for job in jobs]
    clashes = sorted({s for s in names if names.count(s) > 1})
    if clashes:
        click.echo(f"error: configs share output names under {out_root}: {', '.join(clashes)}", err=True)
        ctx.exit(2)
    rows: list[dict] = [_row(job, "skipped") for job in jobs]
    bar = _progress_bar(ctx, len(jobs), no_progress)
    try:
        if remote or workers > 1:
            code = _run_distributed(ctx, jobs, rows, bar, out_root=out_root, seed=seed, overwrite=overwrite,
                                    workers=workers, scheduler=scheduler, scheduler_file=scheduler_file,
                                    timeout=connect_timeout, retries=retries, previews=previews)
            if code:
                ctx.exit(code)
        else:
            for i, job in enumerate(jobs):
                try:
                    job.out = str(_out_dir(job, out_root))
                except Exception as exc:
                    with _above(bar):
                        rows[i] = _failed(ctx, rows[i], exc)
                    bar.update()
                    continue
                with _above(bar):
                    rows[i] = _run_one(ctx, rows[i], job.out, seed, job.overrides, overwrite, no_progress, previews)
                bar.update()
    finally:
        bar.close()
        _write_batch(Path(out_root), rows)
    if as_json:
        click.echo(json.dumps([r | {"ok": r["status"] == "ok"} for r in rows], indent=2))
    failed = [r for r in rows if r["status"] not in ("ok", "degraded") or r["exit_code"]]
    if verbosity(ctx) >= 0:
        click.echo(f"run: {len(rows) - len(failed)} succeeded, {len(failed)} failed", err=True)
        for r in failed:
            where = f" [{batch.folder_name(Path(r['config']).stem, r['sweep'])}]" if r["sweep"] else ""
            click.echo(f"  failed: {r['config']}{where} (exit {r['exit_code']}): {r['error']}", err=True)
    ctx.exit(next((r["exit_code"] for r in failed), 0))


def _row(job, status: str) -> dict:
    return {"config": job.config, "overrides": list(job.set_overrides), "sweep": dict(job.sweep), "status": status,
            "exit_code": None, "seconds": None, "out": None, "worker": None, "metrics": {}, "error": None}


def _out_dir(job, out_root: str) -> Path:
    """The output folder of ``job``: ``default_out_dir`` without a sweep, the sweep's name beside it."""
    from synthkit import batch, outdir
    from synthkit.errors import ConfigError
    from synthkit.runner import default_out_dir

    if not job.sweep:
        return default_out_dir(job.config, out_root)
    target = Path(out_root) / batch.folder_name(outdir.output_name(job.config), job.sweep)
    if not outdir.inside(target, Path(out_root)):
        raise ConfigError(f"{job.config}: output folder {target} would lie outside {out_root}")
    return target


def _run_one(ctx, row: dict, out_dir: str, seed, overrides, overwrite: bool, no_progress: bool,
             previews: str = "all") -> dict:
    """Run one config into ``out_dir`` in this process; return its batch row (failures are recorded,
    not raised)."""
    from synthkit.runner import run_config

    row = row | {"worker": IN_PROCESS}
    start = time.perf_counter()
    try:
        report = run_config(row["config"], out_dir=out_dir, seed=seed, overrides=overrides, overwrite=overwrite,
                            show_progress=not no_progress and verbosity(ctx) >= 0, budget=run_budget(ctx),
                            previews=previews)
    except Exception as exc:
        failed = _failed(ctx, row, exc)
        failed["seconds"] = round(time.perf_counter() - start, 3)
        return failed
    print_summary(ctx, report, out_dir)
    return _succeeded(ctx, row, report, out_dir, round(time.perf_counter() - start, 3))


def _succeeded(ctx, row: dict, report: dict, out_dir: str, seconds: float) -> dict:
    """The row of a run that wrote its outputs: ``ok``, or ``degraded`` (exit 3 with ``--strict``)."""
    metrics = {k: v for k, v in report.get("metrics", {}).items() if k in HEADLINE_METRICS}
    row = row | {"status": "ok", "exit_code": 0, "seconds": seconds, "out": out_dir, "metrics": metrics,
                 "report": report}
    if report.get("status") == "degraded":
        strict = strict_mode(ctx)
        row |= {"status": "degraded", "exit_code": 3 if strict else 0,
                "error": "output degraded" + (" (--strict)" if strict else "")}
    return row


def _failed(ctx, row: dict, exc: Exception) -> dict:
    """Print ``exc`` as one line and return ``row`` marked failed with its exit code and line."""
    code, line = describe_exception(exc)
    if verbosity(ctx) > 0:
        traceback.print_exc(file=sys.stderr)
    return _failed_line(ctx, row, code, line)


def _failed_line(ctx, row: dict, code: int, line: str) -> dict:
    path = row["config"]
    click.echo(f"error: {path}: {line}" if not line.startswith(str(path)) else f"error: {line}", err=True)
    return row | {"status": "failed", "exit_code": code, "error": line}


def _run_distributed(ctx, jobs, rows, bar, *, out_root, seed, overwrite, workers, scheduler, scheduler_file,
                     timeout, retries, previews="all") -> int:
    """Run ``jobs`` on Dask, filling ``rows``; return 0, or the exit code of a cluster that cannot be used
    (its line printed). Configs are validated here first, with the same errors as a sequential run."""
    from synthkit import batch, outdir
    from synthkit.runner import load_method_config

    remote = bool(scheduler or scheduler_file)
    files: set[str] = set()
    tasks: dict[int, dict] = {}
    root = ctx.find_root()
    gib = root.obj.get("max_memory") if root.obj else None
    for i, job in enumerate(jobs):
        try:
            job.out = str(_out_dir(job, out_root))
            named: list[Path] = []
            _, _, inputs = load_method_config(Path(job.config), overrides=job.overrides, seed=seed,
                                              named_inputs=named)
        except Exception as exc:
            with _above(bar):
                rows[i] = _failed(ctx, rows[i], exc)
            bar.update()
            continue
        files.update(os.path.abspath(p) for p in [job.config, *named, *inputs])
        tasks[i] = {"config": os.path.abspath(job.config) if remote else job.config,
                    "out_dir": os.path.abspath(job.out) if remote else job.out,
                    "seed": seed, "overrides": job.overrides, "overwrite": overwrite,
                    "max_bytes": None if gib is None else int(gib * 2**30), "verbosity": verbosity(ctx),
                    "previews": previews}
    if not tasks:
        return 0
    cluster = client = None
    try:
        if remote:
            address = scheduler or batch.read_scheduler_file(scheduler_file)
            what = f"--scheduler {scheduler}" if scheduler else f"--scheduler-file {scheduler_file} ({address})"
            client = batch.connect(address, timeout=timeout, what=what)
            batch.check_workers(client, sorted(files), out_root)
        else:
            from distributed import Client

            cluster = batch.local_cluster(workers)
            client = Client(cluster, set_as_default=False)
        batch.prepare_workers(client)
    except batch.ClusterError as exc:
        for handle in (client, cluster):
            if handle is not None:
                handle.close()
        click.echo(f"error: {exc}", err=True)
        return 2
    order = list(tasks)

    def done(k: int, outcome: dict) -> None:
        i = order[k]
        row = rows[i] | {"worker": outcome["worker"], "seconds": outcome["seconds"]}
        if outcome.get("attempts", 1) > 1:
            row["attempts"] = outcome["attempts"]
        with _above(bar):
            if outcome["status"] == "ok":
                print_summary(ctx, outcome["report"], jobs[i].out)
                rows[i] = _succeeded(ctx, row, outcome["report"], jobs[i].out, outcome["seconds"])
            else:
                if outcome.get("traceback") and verbosity(ctx) > 0:
                    click.echo(outcome["traceback"].rstrip(), err=True)
                rows[i] = _failed_line(ctx, row, outcome["exit_code"], outcome["error"])
                if outcome.get("died"):
                    outdir.remove_leftovers(Path(jobs[i].out).absolute())
        bar.update()

    try:
        batch.run_on_dask(client, [tasks[i] for i in order], retries=retries, on_done=done)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()  # interrupted: the workers are gone, so are their runs' staging folders
            for i in order:
                if rows[i]["status"] == "skipped":
                    outdir.remove_leftovers(Path(jobs[i].out).absolute())
    return 0


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


def _write_batch(out_root: Path, rows: list[dict]) -> None:
    """Write ``batch.json`` (one row per config, without full reports) into ``out_root``, unless a
    file of that name exists there that synthkit did not write."""
    from synthkit import __version__
    from synthkit.runner import write_json

    path = out_root / BATCH_FILE
    if path.exists():
        try:
            ours = "synthkit_batch" in json.loads(path.read_text())
        except (OSError, ValueError, TypeError):
            ours = False
        if not ours:
            click.echo(f"warning: {path} exists and was not written by synthkit; batch.json not written", err=True)
            return
    out_root.mkdir(parents=True, exist_ok=True)
    write_json(path, {"synthkit_batch": __version__, "runs": [{k: v for k, v in r.items() if k != "report"}
                                                               for r in rows]})
