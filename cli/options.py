"""Options shared by the subcommands, the error handling wrapper and the method command factory."""

from __future__ import annotations

import functools
import json
import sys
import traceback
from collections.abc import Callable

import click

from synthkit.errors import Terminated
from synthkit.logs import configure_logging, describe_exception
from synthkit.methods.spec import DEFAULT_SET_EXAMPLE
from synthkit.summary import headline

SET_HELP = "Override a config key (repeatable; values are YAML), e.g. --set {example}."

config_argument = click.argument("config", type=click.Path(dir_okay=False, path_type=str))
seed_option = click.option(
    "--seed", type=click.IntRange(0, 2**32 - 1), default=None, help="Seed (overrides the config's seed)."
)


def set_option_for(example: str = DEFAULT_SET_EXAMPLE):
    """The repeatable ``--set KEY.PATH=VALUE`` option, its help showing ``example``."""
    return click.option("--set", "overrides", multiple=True, metavar="KEY.PATH=VALUE",
                        help=SET_HELP.format(example=example))


set_option = set_option_for()
overwrite_option = click.option("--overwrite", is_flag=True, help="Replace an existing output folder.")
progress_option = click.option("--no-progress", is_flag=True, help="Do not show progress bars.")
json_option = click.option("--json", "as_json", is_flag=True, help="Print the report as JSON on stdout.")
name_outputs_option = click.option(
    "--name-outputs", is_flag=True,
    help="Also write the summary preview and the main result as <run>.preview.png and <run>.<suffix> "
         "(hard links), so that files gathered from many runs keep apart.")
previews_option = click.option(
    "--previews", type=click.Choice(["all", "summary", "none"]), default="all", show_default=True,
    help="PNG previews to render: every one, the one summary image of each run, or none (results and "
         "report.json are written either way).")


def _set_root(key: str, transform=None):
    """A click callback storing an option given after the subcommand into the group's ``ctx.obj``
    (so ``synthkit reshape cfg.yaml -q`` means what ``synthkit -q reshape cfg.yaml`` does)."""

    def callback(ctx: click.Context, param: click.Parameter, value):
        if value in (None, False, 0):
            return value
        root = ctx.find_root()
        root.obj = root.obj or {}
        root.obj[key] = transform(value) if transform else value
        if key == "verbosity":
            configure_logging(root.obj[key])
        return value

    return callback


def nan_refused(value: float | None) -> float | None:
    """``value`` unless it is NaN (which passes click's range checks), as a usage error."""
    if value is not None and value != value:
        raise click.BadParameter(f"{value} is not a number", param_hint="--max-memory")
    return value


def global_options(command: Callable) -> Callable:
    """The group's -v/-q/--max-memory/--strict, accepted after a subcommand's name too."""
    options = [
        click.option("-v", "--verbose", count=True, expose_value=False, callback=_set_root("verbosity",
                     lambda n: min(n, 2)), help="More messages; -v also shows tracebacks (also before the command)."),
        click.option("-q", "--quiet", is_flag=True, expose_value=False, callback=_set_root("verbosity", lambda _: -1),
                     help="Only errors on stderr (also before the command)."),
        click.option("--max-memory", type=click.FloatRange(min=0.01, max=1e6), default=None, metavar="GIB",
                     expose_value=False, callback=_set_root("max_memory", nan_refused),
                     help="Memory one run may plan to use, in GiB (also before the command)."),
        click.option("--strict", is_flag=True, expose_value=False, callback=_set_root("strict"),
                     help="Exit 3 when an output is over its quality limits, 2 for a painted colour that names "
                          "no region (also before the command)."),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def verbosity(ctx: click.Context) -> int:
    """-1 quiet, 0 normal, 1 verbose (from the group's -v/-q)."""
    root = ctx.find_root()
    return int(root.obj.get("verbosity", 0)) if root.obj else 0


def strict_mode(ctx: click.Context) -> bool:
    """The group's ``--strict``: a degraded output exits 3."""
    root = ctx.find_root()
    return bool(root.obj.get("strict")) if root.obj else False


def run_settings(ctx: click.Context, *, seed, overwrite: bool, no_progress: bool, previews: str,
                 name_outputs: bool):
    """The :class:`~synthkit.runner.RunSettings` of every run of this command: its options and the
    group's ``--max-memory`` (GiB), ``--strict`` and ``-v``/``-q``."""
    from synthkit.runner import RunSettings

    root = ctx.find_root()
    gib = root.obj.get("max_memory") if root.obj else None
    return RunSettings(seed=seed, overwrite=overwrite, show_progress=not no_progress and verbosity(ctx) >= 0,
                       max_bytes=None if gib is None else int(gib * 2**30), previews=previews,
                       strict=strict_mode(ctx), name_outputs=name_outputs, verbosity=verbosity(ctx))


def report_errors(fn: Callable) -> Callable:
    """Turn exceptions into one line on stderr and the documented exit code (traceback with -v)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        ctx = click.get_current_context()
        try:
            return fn(*args, **kwargs)
        except click.exceptions.Exit:
            raise
        except click.ClickException:
            raise
        except KeyboardInterrupt:
            click.echo("error: interrupted", err=True)
            ctx.exit(130)
        except Terminated:
            click.echo("error: terminated (SIGTERM)", err=True)
            ctx.exit(Terminated.exit_code)
        except Exception as exc:
            code, line = describe_exception(exc)
            if verbosity(ctx) > 0:
                traceback.print_exc(file=sys.stderr)
            click.echo(f"error: {line}", err=True)
            ctx.exit(code)

    return wrapper


def print_summary(ctx: click.Context, report: dict, out_dir: str) -> None:
    """One line per run on stderr (unless -q): method, folder, seconds, headline metrics."""
    if verbosity(ctx) < 0:
        return
    shown = headline(report.get("metrics", {}), report.get("method"))
    text = ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in shown.items())
    status = "" if report.get("status", "ok") == "ok" else f" [{report['status']}]"
    click.echo(f"{report['method']}: wrote {out_dir} in {report['timings']['total']:.2f} s ({text}){status}",
               err=True)


def method_command(
    name: str,
    help_text: str,
    *,
    flags: dict[str, tuple[str, str]] | None = None,
    set_example: str = DEFAULT_SET_EXAMPLE,
) -> click.Command:
    """Build the click command for method ``name``; ``set_example`` is its ``--set`` help example.

    ``flags`` maps an extra boolean option name (e.g. ``--analyze-only``) to ``(override, help)``:
    giving the flag adds the ``--set`` override ``override`` (e.g. ``analyze_only=true``).
    """
    flags = flags or {}

    @click.command(name=name, help=help_text)
    @config_argument
    @click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=str), default=None,
                  help="Output folder (default: out/<config name>).")
    @seed_option
    @set_option_for(set_example)
    @overwrite_option
    @progress_option
    @previews_option
    @json_option
    @name_outputs_option
    @global_options
    @report_errors
    def command(config, out_dir, seed, overrides, overwrite, no_progress, previews, as_json, name_outputs, **extra):
        from synthkit.runner import default_out_dir, run_config

        ctx = click.get_current_context()
        extra_sets = [flags[_flag_name(k)][0] for k, on in extra.items() if on]
        out = out_dir or str(default_out_dir(config))
        settings = run_settings(ctx, seed=seed, overwrite=overwrite, no_progress=no_progress, previews=previews,
                                name_outputs=name_outputs)
        report = run_config(config, method=name, out_dir=out, overrides=[*extra_sets, *overrides], settings=settings)
        if as_json:
            click.echo(json.dumps(report, indent=2))
        print_summary(ctx, report, out)

    for flag, (_override, flag_help) in flags.items():
        command = click.option(flag, is_flag=True, help=flag_help)(command)
    return command


def _flag_name(param: str) -> str:
    return "--" + param.replace("_", "-")
