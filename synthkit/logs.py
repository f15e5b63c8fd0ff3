"""Messages to the user: where log records go, and an exception as one line with its exit code
(used by the command line and by batch workers alike; imports nothing heavy)."""

from __future__ import annotations

import logging
import sys

__all__ = ["configure_logging", "describe_exception"]


def configure_logging(verbosity_level: int) -> None:
    """Log to stderr: warnings by default, info with -v (1), debug with -vv (2), errors only with -q (-1)."""
    level = {-1: logging.ERROR, 0: logging.WARNING, 1: logging.INFO}.get(verbosity_level, logging.DEBUG)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger("synthkit")
    root.handlers[:] = [handler]
    root.setLevel(level)
    root.propagate = False


def describe_exception(exc: BaseException) -> tuple[int, str]:
    """(exit code, one-line message) for an exception raised by a run."""
    from synthkit.errors import SynthkitError

    if isinstance(exc, SynthkitError):
        return exc.exit_code, str(exc)
    if isinstance(exc, MemoryError):
        return 1, "out of memory"
    text = str(exc).splitlines()[0] if str(exc) else ""
    return 1, f"internal error: {type(exc).__name__}: {text} (run with -v for the traceback)"
