"""``synthkit validate CONFIG...``: check configs (schema, referenced files) without running."""

from __future__ import annotations

import click

from .options import config_argument, set_option, verbosity


@click.command(name="validate")
@click.argument("configs", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=str))
@set_option
@click.pass_context
def command(ctx: click.Context, configs: tuple[str, ...], overrides: tuple[str, ...]) -> None:
    """Check each CONFIG against its method's schema and that the files it names exist.

    Keeps going past a bad config; exits with the first failure's code (2 for a config error,
    3 for an input file that does not exist), 0 when every config is valid.
    """
    from synthkit.errors import SynthkitError
    from synthkit.runner import load_method_config

    first_failure = 0
    for path in configs:
        try:
            method, _cfg, inputs = load_method_config(path, overrides=overrides)
        except SynthkitError as exc:
            first_failure = first_failure or exc.exit_code
            click.echo(f"error: {exc}", err=True)
            continue
        if verbosity(ctx) >= 0:
            click.echo(f"ok: {path} ({method}, {len(inputs)} input file(s))", err=True)
    ctx.exit(first_failure)


__all__ = ["command", "config_argument"]
