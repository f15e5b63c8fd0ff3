"""``synthkit validate CONFIG...``: check configs and batch files (schema, referenced files) without running."""

from __future__ import annotations

import click

from .options import config_argument, set_option, verbosity


def _checks(path: str, overrides: tuple[str, ...]) -> tuple[bool, list]:
    """Whether ``path`` is a batch file, and the (config, overrides) pairs to validate for it:
    itself, or for a batch file each of its configs with its ``set:`` and with each sweep value
    its method has (one value at a time)."""
    from synthkit import plan

    spec = plan.read_batch_file(path)
    if spec is None:
        return False, [(path, list(overrides))]
    pairs = []
    for config in spec.configs:
        base = [*spec.overrides, *overrides]
        kept, _ = plan.axes_for(plan.config_method(config), spec.axes)
        pairs.append((config, base))
        pairs += [(config, [*base, f"{key}={value}"]) for key, values in kept for value in values]
    return True, pairs


@click.command(name="validate")
@click.argument("configs", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=str))
@set_option
@click.pass_context
def command(ctx: click.Context, configs: tuple[str, ...], overrides: tuple[str, ...]) -> None:
    """Check each CONFIG (or batch file) against its method's schema and that the files it names exist.

    A batch file's configs are checked with its ``set:`` values and each of its sweep values.
    Keeps going past a bad config; exits with the first failure's code (2 for a config error,
    3 for an input file that does not exist), 0 when every config is valid.
    """
    from synthkit.errors import SynthkitError
    from synthkit.runner import load_method_config

    first_failure = 0
    for path in configs:
        try:
            is_batch, checks = _checks(path, overrides)
        except SynthkitError as exc:
            first_failure = first_failure or exc.exit_code
            click.echo(f"error: {exc}", err=True)
            continue
        for config, sets in checks:
            try:
                method, _cfg, inputs = load_method_config(config, overrides=sets)
            except SynthkitError as exc:
                first_failure = first_failure or exc.exit_code
                click.echo(f"error: {exc}", err=True)
                break
        else:
            if verbosity(ctx) >= 0:
                what = (f"batch file, {len({c for c, _ in checks})} configs, {len(checks)} checks" if is_batch
                        else f"{method}, {len(inputs)} input file(s)")
                click.echo(f"ok: {path} ({what})", err=True)
    ctx.exit(first_failure)


__all__ = ["command", "config_argument"]
