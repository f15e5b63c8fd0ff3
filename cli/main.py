"""The ``synthkit`` command group: -v/-q, --version, and the subcommands (imports no numpy)."""

from __future__ import annotations

import click

from synthkit import __version__
from synthkit.methods import available_methods, package_module

from .options import configure_logging, method_command


class _Group(click.Group):
    """Lists the method subcommands that are implemented, then ``validate`` and ``run``."""

    def list_commands(self, ctx):
        return [*available_methods(), "validate", "run"]

    def get_command(self, ctx, name):
        if name == "validate":
            from .validate import command
        elif name == "run":
            from .run import command
        elif name in available_methods():
            package = package_module(name)
            help_text = (package.__doc__ or name).strip().splitlines()[0]
            command = method_command(name, help_text, flags=getattr(package, "CLI_FLAGS", None))
        else:
            return None
        return command


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="synthkit")
@click.option("-v", "--verbose", count=True, help="More messages; -v also shows tracebacks.")
@click.option("-q", "--quiet", is_flag=True, help="Only errors on stderr.")
@click.pass_context
def cli(ctx: click.Context, verbose: int, quiet: bool) -> None:
    """Example-based 3D model and texture synthesis, driven by YAML configs.

    Exit codes: 0 success, 2 usage or config error, 3 input data error, 1 anything else.
    """
    level = -1 if quiet else min(verbose, 2)
    ctx.obj = {"verbosity": level}
    configure_logging(level)


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="synthkit")
