"""``synthkit report OUT_ROOT``: (re)write the review page of a folder of runs."""

from __future__ import annotations

import click

from .options import verbosity


@click.command(name="report")
@click.argument("out_root", type=click.Path(exists=True, file_okay=False, path_type=str))
@click.pass_context
def command(ctx: click.Context, out_root: str) -> None:
    """Write OUT_ROOT/index.html: a card per run with its summary preview, a sortable, filterable
    table of every run and a page per run (previews, config, report). Static and self-contained:
    open it in a browser. Exits 2 when OUT_ROOT holds an index.html synthkit did not write."""
    from synthkit.review import write_review

    try:
        index = write_review(out_root)
    except ValueError as exc:
        click.echo(f"error: {exc}", err=True)
        ctx.exit(2)
    if verbosity(ctx) >= 0:
        click.echo(f"review: {index}", err=True)
