"""``synthkit run CONFIG...``: run many configs, each by its ``method:`` key, for batch jobs."""

from __future__ import annotations

import json
import sys
import traceback
from pathlib import Path

import click

from .options import (
    describe_exception,
    json_option,
    overwrite_option,
    print_summary,
    progress_option,
    seed_option,
    set_option,
    verbosity,
)


@click.command(name="run")
@click.argument("configs", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=str))
@click.option("--out-root", type=click.Path(file_okay=False, path_type=str), default="out", show_default=True,
              help="Each config writes into OUT_ROOT/<config file name without suffix>.")
@seed_option
@set_option
@overwrite_option
@progress_option
@json_option
@click.pass_context
def command(ctx, configs, out_root, seed, overrides, overwrite, no_progress, as_json) -> None:
    """Run every CONFIG, dispatching on its `method:` key.

    A failed config is reported and the batch goes on; at the end the command exits with the
    exit code of the first failure (0 when all succeeded).
    """
    from synthkit.runner import run_config

    stems = [Path(c).stem for c in configs]
    clashes = sorted({s for s in stems if stems.count(s) > 1})
    if clashes:
        click.echo(f"error: configs share output names under {out_root}: {', '.join(clashes)}", err=True)
        ctx.exit(2)
    results = []
    first_failure = 0
    for path, stem in zip(configs, stems, strict=True):
        out_dir = str(Path(out_root) / stem)
        try:
            report = run_config(path, out_dir=out_dir, seed=seed, overrides=overrides, overwrite=overwrite,
                                show_progress=not no_progress and verbosity(ctx) >= 0)
        except Exception as exc:
            code, line = describe_exception(exc)
            if verbosity(ctx) > 0:
                traceback.print_exc(file=sys.stderr)
            click.echo(f"error: {path}: {line}" if not line.startswith(str(path)) else f"error: {line}", err=True)
            first_failure = first_failure or code
            results.append({"config": path, "ok": False, "exit_code": code, "error": line})
            continue
        print_summary(ctx, report, out_dir)
        results.append({"config": path, "ok": True, "out": out_dir, "report": report})
    if as_json:
        click.echo(json.dumps(results, indent=2))
    failed = sum(not r["ok"] for r in results)
    if verbosity(ctx) >= 0:
        click.echo(f"run: {len(results) - failed} succeeded, {failed} failed", err=True)
    ctx.exit(first_failure)
