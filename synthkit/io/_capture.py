"""Capture what C libraries print on file descriptor 2 while synthkit calls into them, and check
that an input file can be opened before a library tries to.

libjpeg, libpng, libtiff and OpenCV's logger write their warnings straight to fd 2 with C stdio,
past ``sys.stderr`` and past :mod:`logging`. :func:`captured_stderr` points fd 2 at a temporary
file for the duration of one call (``dup2``, restored in ``finally``) and hands back the lines,
so that the caller decides what they mean and the user sees at most one line in synthkit's words.

Redirection is process-wide: one lock serialises the captures, and anything another thread
writes to fd 2 during a capture (a call is a few milliseconds: one image decode) is captured with
it. If fd 2 is closed or cannot be duplicated, the call runs uncaptured.
"""

from __future__ import annotations

import contextlib
import os
import stat
import sys
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

from synthkit.errors import InputError

_LOCK = threading.RLock()


@contextlib.contextmanager
def captured_stderr() -> Iterator[list[str]]:
    """Redirect fd 2 into a temporary file for the ``with`` body.

    Yields a list that is filled, once the body has finished (normally or not), with the lines
    written to fd 2 meanwhile (decoded as UTF-8 with replacement, trailing whitespace stripped,
    empty lines dropped).
    """
    lines: list[str] = []
    with _LOCK:
        with contextlib.suppress(Exception):
            sys.stderr.flush()
        try:
            saved = os.dup(2)
        except OSError:
            yield lines
            return
        with tempfile.TemporaryFile() as sink:
            try:
                os.dup2(sink.fileno(), 2)
                try:
                    yield lines
                finally:
                    with contextlib.suppress(Exception):
                        sys.stderr.flush()
                    os.dup2(saved, 2)
            finally:
                os.close(saved)
                sink.seek(0)
                text = sink.read().decode("utf-8", "replace")
                lines.extend(line.rstrip() for line in text.splitlines() if line.strip())


def check_readable(path: Path, what: str) -> int:
    """Raise :class:`InputError` unless ``path`` is a regular file this process may open for
    reading; return its size in bytes. ``what`` ("image", "mesh") names the file in the messages:
    ``<path>: <what> file not found``, ``<path>: permission denied (cannot read <what>)``,
    ``<path>: is a folder, not an image file``."""
    try:
        st = path.stat()
    except (FileNotFoundError, NotADirectoryError):
        raise InputError(f"{path}: {what} file not found") from None
    except PermissionError:
        raise InputError(f"{path}: permission denied (cannot read {what})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    article = "an" if what[:1] in "aeiou" else "a"
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{path}: is a folder, not {article} {what} file")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{path}: is not a regular file ({article} {what} file is needed)")
    try:
        with open(path, "rb"):
            pass
    except PermissionError:
        raise InputError(f"{path}: permission denied (cannot read {what})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    return st.st_size
