"""``synthkit run CONFIG...``: run many configs, each by its ``method:`` key, for batch jobs."""

from __future__ import annotations

import json
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
    print_summary,
    progress_option,
    run_budget,
    seed_option,
    set_option,
    verbosity,
)

BATCH_FILE = "batch.json"


@click.command(name="run")
@click.argument("configs", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=str))
@click.option("--out-root", type=click.Path(file_okay=False, path_type=str), default="out", show_default=True,
              help="Each config writes into OUT_ROOT/<config file name without suffix>; batch.json goes here.")
@seed_option
@set_option
@overwrite_option
@progress_option
@json_option
@click.pass_context
def command(ctx, configs, out_root, seed, overrides, overwrite, no_progress, as_json) -> None:
    """Run every CONFIG, dispatching on its `method:` key.

    A failed config is reported and the batch goes on; at the end every failure is listed, the
    rows are written to OUT_ROOT/batch.json, and the command exits with the exit code of the first
    failure (0 when all succeeded).
    """
    from synthkit.runner import default_out_dir

    names = [Path(c).stem for c in configs]
    clashes = sorted({s for s in names if names.count(s) > 1})
    if clashes:
        click.echo(f"error: configs share output names under {out_root}: {', '.join(clashes)}", err=True)
        ctx.exit(2)
    rows: list[dict] = [_row(path, overrides, "skipped") for path in configs]
    try:
        for i, path in enumerate(configs):
            try:
                out_dir = str(default_out_dir(path, out_root))
            except Exception as exc:
                rows[i] = _failed(ctx, rows[i], exc)
                continue
            rows[i] = _run_one(ctx, rows[i], out_dir, seed, overrides, overwrite, no_progress)
    finally:
        _write_batch(Path(out_root), rows)
    if as_json:
        click.echo(json.dumps([r | {"ok": r["status"] == "ok"} for r in rows], indent=2))
    failed = [r for r in rows if r["status"] != "ok"]
    if verbosity(ctx) >= 0:
        click.echo(f"run: {len(rows) - len(failed)} succeeded, {len(failed)} failed", err=True)
        for r in failed:
            click.echo(f"  failed: {r['config']} (exit {r['exit_code']})", err=True)
    ctx.exit(next((r["exit_code"] for r in failed), 0))


def _row(path: str, overrides, status: str) -> dict:
    return {"config": path, "overrides": list(overrides), "status": status, "exit_code": None,
            "seconds": None, "out": None, "metrics": {}, "error": None}


def _run_one(ctx, row: dict, out_dir: str, seed, overrides, overwrite: bool, no_progress: bool) -> dict:
    """Run one config into ``out_dir``; return its batch row (failures are recorded, not raised)."""
    from synthkit.runner import run_config

    start = time.perf_counter()
    try:
        report = run_config(row["config"], out_dir=out_dir, seed=seed, overrides=overrides, overwrite=overwrite,
                            show_progress=not no_progress and verbosity(ctx) >= 0, budget=run_budget(ctx))
    except Exception as exc:
        failed = _failed(ctx, row, exc)
        failed["seconds"] = round(time.perf_counter() - start, 3)
        return failed
    print_summary(ctx, report, out_dir)
    metrics = {k: v for k, v in report.get("metrics", {}).items() if k in HEADLINE_METRICS}
    return row | {"status": "ok", "exit_code": 0, "seconds": round(time.perf_counter() - start, 3),
                  "out": out_dir, "metrics": metrics, "report": report}


def _failed(ctx, row: dict, exc: Exception) -> dict:
    """Print ``exc`` as one line and return ``row`` marked failed with its exit code and line."""
    code, line = describe_exception(exc)
    if verbosity(ctx) > 0:
        traceback.print_exc(file=sys.stderr)
    path = row["config"]
    click.echo(f"error: {path}: {line}" if not line.startswith(str(path)) else f"error: {line}", err=True)
    return row | {"status": "failed", "exit_code": code, "error": line}


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
