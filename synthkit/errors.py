"""Errors a user can fix, each with its own exit code.

``ConfigError`` (exit 2) is a problem with the command line or a config file: an unknown key,
a value out of range, a missing config file. ``InputError`` (exit 3) is a problem with input
data: a mesh or image a config names that does not exist, cannot be read or is degenerate.
Any other exception is a bug or an environment problem and exits with 1.
"""

import contextlib
import threading
from collections.abc import Iterator


class SynthkitError(Exception):
    """Base class for errors reported to the user as one line, without a traceback.

    ``keep_outputs=True`` marks a refusal whose diagnostics are worth keeping (for example the
    offset statistics of a mesh with no repetition): the runner then still moves the output folder
    into place, with ``report.json`` saying ``"status": "refused"`` and the message, before the
    error reaches the user with its exit code. Such a refusal may carry ``result``: the partial
    :class:`~synthkit.result.Result` (the statistics) the runner writes into that folder.
    """

    exit_code = 1

    def __init__(self, message: str, *, keep_outputs: bool = False, result=None):
        super().__init__(message)
        self.keep_outputs = keep_outputs
        self.result = result


class ConfigError(SynthkitError):
    """A usage or configuration error: bad option, bad config key or value (exit code 2)."""

    exit_code = 2


class InputError(SynthkitError):
    """Input data that is missing, unreadable or degenerate (exit code 3)."""

    exit_code = 3


class QualityError(SynthkitError):
    """An output over its method's mesh-quality limits under ``--strict`` (exit code 3); the
    output folder is written, with ``report.json`` saying ``"status": "degraded"``."""

    exit_code = 3


class KeyedError(ValueError):
    """A value a method's stage refuses. Stage code knows no exit codes: its method's pipeline turns
    this into a :class:`ConfigError` or :class:`InputError`. ``key`` names the config entry at fault
    as the stage knows it (a whole key such as ``"target.steps[1]=1"``, or a key within the section
    the pipeline adds), or is None when the input itself is at fault; ``message`` says what is
    wrong. ``str()`` is ``"<key>: <message>"``, or the message alone without a key."""

    def __init__(self, key: str | None, message: str):
        super().__init__(f"{key}: {message}" if key else message)
        self.key = key
        self.message = message


def user_error(exc: KeyedError, prefix: str = "", section: str = "", *,
               keyed: type[SynthkitError] = ConfigError) -> SynthkitError:
    """The user's error for a stage's refusal ``exc``: ``keyed`` (a ConfigError unless the caller
    knows the input is at fault) reading ``<prefix><section>.<key>: <message>`` when it names a key,
    else an InputError reading ``<prefix><message>``. ``prefix`` is usually ``"<file>: "``."""
    if exc.key is None:
        return InputError(prefix + exc.message)
    where = f"{section}.{exc.key}" if section else exc.key
    return keyed(f"{prefix}{where}: {exc.message}")


@contextlib.contextmanager
def refusals(prefix: str = "", section: str = "", *, keyed: type[SynthkitError] = ConfigError) -> Iterator[None]:
    """Raise a :class:`KeyedError` of the block again as its :func:`user_error`."""
    try:
        yield
    except KeyedError as exc:
        raise user_error(exc, prefix, section, keyed=keyed) from None


class Terminated(BaseException):
    """The process received SIGTERM (from ``timeout``, a batch scheduler or ``kill``): unwinds like
    KeyboardInterrupt, so staging folders are removed, and exits with 128 + 15 = 143."""

    exit_code = 143


TERMINATION_REQUESTED = threading.Event()
"""Set by the CLI's SIGTERM handler before it raises :class:`Terminated`. A library may swallow
that exception (OpenCV's import runs a bare ``except:``; a SIGTERM arriving there was lost and the
run went on to exit 0), so :func:`raise_if_terminated` raises it again at every stage boundary and
before an output is moved into place."""


def raise_if_terminated() -> None:
    """Raise :class:`Terminated` when SIGTERM was received (:data:`TERMINATION_REQUESTED`)."""
    if TERMINATION_REQUESTED.is_set():
        raise Terminated()
