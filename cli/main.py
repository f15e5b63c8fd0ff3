"""The ``synthkit`` command group: -v/-q, --max-memory, --version, and the subcommands (imports no numpy).

Every error, click's usage errors included, is one ``error: ...`` line on stderr with its exit code
(2 for usage); SIGTERM unwinds like Ctrl-C (staging folders removed) and exits 143.
"""

from __future__ import annotations

import signal
import sys

import click

from synthkit import __version__
from synthkit.errors import TERMINATION_REQUESTED, Terminated
from synthkit.methods import available_methods, package_module, spec

from .options import configure_logging, method_command, nan_refused

_TOOLS = ("init", "schema", "validate", "run", "report")
"""Subcommands that are not methods, after the methods in ``--help``."""


def _raise_terminated(signum, frame):
    TERMINATION_REQUESTED.set()
    raise Terminated()


def _install_sigterm():
    """Make SIGTERM raise :class:`Terminated` (and set ``TERMINATION_REQUESTED``, in case a library
    swallows the exception); return the previous handler (None off the main thread)."""
    try:
        previous = signal.signal(signal.SIGTERM, _raise_terminated)
    except ValueError:
        return None
    TERMINATION_REQUESTED.clear()
    return previous


class _Group(click.Group):
    """Lists the method subcommands that are implemented, then the tools; usage errors in one line."""

    def list_commands(self, ctx):
        return [*available_methods(), *_TOOLS]

    def get_command(self, ctx, name):
        if name in _TOOLS:
            module = __import__(f"{__package__}.{name}", fromlist=["command"])
            return module.command
        if name in available_methods():
            help_text = (package_module(name).__doc__ or name).strip().splitlines()[0]
            declared = spec(name)
            return method_command(name, help_text, flags=declared.cli_flags, set_example=declared.set_example)
        return None

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        """click's main, with a usage error as one line (exit 2) and SIGTERM as exit 143."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        previous = _install_sigterm()
        try:
            code = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except click.UsageError as exc:
            click.echo(f"error: {exc.format_message()}", err=True)
            code = exc.exit_code
        except click.ClickException as exc:
            click.echo(f"error: {exc.format_message()}", err=True)
            code = exc.exit_code
        except click.Abort:
            click.echo("error: interrupted", err=True)
            code = 130
        except Terminated:
            click.echo("error: terminated (SIGTERM)", err=True)
            code = Terminated.exit_code
        finally:
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)
        sys.exit(code if isinstance(code, int) else 0)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="synthkit")
@click.option("-v", "--verbose", count=True, help="More messages; -v also shows tracebacks.")
@click.option("-q", "--quiet", is_flag=True, help="Only errors on stderr.")
@click.option("--max-memory", type=click.FloatRange(min=0.01, max=1e6), default=None, metavar="GIB",
              callback=lambda ctx, param, value: nan_refused(value),
              help="Memory one run may plan to use, in GiB (default: half of this machine's memory); "
                   "work estimated beyond it is refused before it starts.")
@click.option("--strict", is_flag=True,
              help="Exit 3 when an output mesh is over its method's quality limits (the run is written, "
                   "its report says degraded); exit 2 for a painted stroke colour that names no region.")
@click.pass_context
def cli(ctx: click.Context, verbose: int, quiet: bool, max_memory: float | None, strict: bool) -> None:
    """Example-based 3D model and texture synthesis, driven by YAML configs.

    Exit codes: 0 success, 2 usage or config error, 3 input data error (and, with --strict, an
    output over its quality limits), 1 anything else; 130 interrupted (Ctrl-C), 143 terminated (SIGTERM).
    """
    level = -1 if quiet else min(verbose, 2)
    ctx.obj = {"verbosity": level, "max_memory": max_memory, "strict": strict}
    configure_logging(level)


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="synthkit")
