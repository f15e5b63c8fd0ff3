"""``synthkit init METHOD [--out FILE]``: a commented YAML config with every key and its default."""

from __future__ import annotations

import click

from synthkit.methods import available_methods


@click.command(name="init")
@click.argument("method", type=click.Choice(available_methods()))
@click.option("--out", "out_file", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Write the config to this new file (default: stdout). An existing file is never replaced.")
@click.pass_context
def command(ctx: click.Context, method: str, out_file: str | None) -> None:
    """Print (or write) a config for METHOD holding every key with its default, range and description.

    Fill the keys marked REQUIRED (input files) and adapt the example values; it then validates.
    """
    import os

    from synthkit.config_template import config_template
    from synthkit.methods import spec
    from synthkit.methods.rooms import config_module

    declared = spec(method)
    text = config_template(config_module(method).CONFIG, method=method, values=declared.init_values,
                           required=declared.init_required)
    if out_file is None:
        click.echo(text, nl=False)
        return
    try:
        fd = os.open(out_file, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        click.echo(f"error: --out {out_file}: file exists; init never replaces a file", err=True)
        ctx.exit(2)
    except OSError as exc:
        click.echo(f"error: --out {out_file}: cannot create: {exc.strerror}", err=True)
        ctx.exit(2)
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
