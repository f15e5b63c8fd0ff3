"""Atomic file writes: a temporary file beside the target, then ``os.replace``.

A reader (or a run killed half-way) sees the old file or the whole new one, never a part.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

__all__ = ["write_bytes_atomic", "write_text_atomic", "replacing_atomically"]


@contextlib.contextmanager
def replacing_atomically(path: Path | str) -> Iterator[Path]:
    """Yield ``<name>.tmp<suffix>`` beside ``path`` for a writer that needs a file name (its format
    chosen by the suffix, as USD's is); on success it replaces ``path``, on failure it is removed."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp" + path.suffix)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_bytes_atomic(path: Path | str, data: bytes) -> None:
    """Write ``data`` to ``path`` through ``<name>.tmp<suffix>`` and a rename."""
    with replacing_atomically(path) as tmp:
        tmp.write_bytes(data)


def write_text_atomic(path: Path | str, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`write_bytes_atomic`)."""
    write_bytes_atomic(path, text.encode("utf-8"))
