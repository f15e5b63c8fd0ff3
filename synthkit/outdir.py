"""Output folders: what may be replaced, names derived from configs, locks, staging and the final move.

Guarantees (README "Output folders"):

- An existing folder is replaced only when it is a previous synthkit output, i.e. it holds both
  :data:`MARKER` (written into every output) and ``report.json``; anything else is refused, with
  or without ``--overwrite``. Without ``--overwrite`` even a synthkit output is kept.
- A folder that holds an input of the run is never an output folder; inputs are compared both
  as the config names them (symlinks kept) and resolved.
- Names derived from config stems are refused when empty, ``.``, ``..``, hidden, or holding a
  path separator, and the folder must lie inside ``--out-root``.
- One run at a time writes a given folder: a lock file ``.NAME.lock`` beside it, taken with
  ``flock`` before any work and removed afterwards; a second run is refused at once.
- Outputs are built in ``.NAME.partial-PID`` beside the target and renamed into place; staging
  and ``.NAME.old-PID`` folders of runs that are gone (killed) are removed by the next run of the
  same name, and so is an empty ``.NAME.partial-PID`` of a gone PID (killed before its marker).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
import socket
from collections.abc import Iterable, Iterator
from pathlib import Path

from synthkit.errors import ConfigError
from synthkit.version import __version__

MARKER = ".synthkit-output"
"""File written into every output folder (and staging folder): JSON with version, host and pid."""

_LEFTOVER_KINDS = ("partial", "old")


def output_name(config_path: Path | str) -> str:
    """The output folder name for a config: its file stem, refused when it could escape or hide."""
    stem = Path(config_path).name
    for suffix in (".yaml", ".yml"):
        if stem.lower().endswith(suffix):
            stem = stem[: -len(suffix)]
            break
    else:
        stem = Path(config_path).stem
    if stem in ("", ".", "..") or stem.startswith(".") or "/" in stem or "\\" in stem or "\0" in stem:
        raise ConfigError(
            f"{config_path}: cannot name an output folder {stem!r} after this config; rename the file or give --out"
        )
    return stem


def inside(folder: Path, root: Path) -> bool:
    """Whether ``folder`` lies strictly inside ``root``, both as written and resolved."""
    folder_abs, root_abs = Path(os.path.abspath(folder)), Path(os.path.abspath(root))
    return root_abs in folder_abs.parents and root_abs.resolve() in folder_abs.resolve().parents


def is_synthkit_output(folder: Path) -> bool:
    """Whether ``folder`` is a folder a synthkit run wrote (marker and report.json)."""
    return (folder / MARKER).is_file() and (folder / "report.json").is_file()


def check_target(out_dir: Path, inputs: Iterable[Path], *, overwrite: bool) -> Path:
    """Refuse an ``--out`` that may not be written; return its absolute (unresolved) path.

    ``inputs`` are every input file of the run, as named and resolved. Raises ConfigError naming
    the option and the reason.
    """
    written = Path(os.path.abspath(out_dir))
    if written.is_symlink():
        raise ConfigError(f"--out {out_dir}: is a symbolic link; give the folder it points to")
    forms = {written, written.resolve()}
    for item in inputs:
        item_abs = Path(os.path.abspath(item))
        for form in forms:
            for candidate in (item_abs, item_abs.resolve()):
                if candidate == form or form in candidate.parents:
                    raise ConfigError(f"--out {out_dir}: output folder holds the input {item}; choose another folder")
    cwd = Path.cwd()
    if any(form == cwd or form in cwd.parents for form in forms) and written.exists():
        raise ConfigError(f"--out {out_dir}: is the current folder or one above it; choose another folder")
    if written.exists():
        if not written.is_dir():
            raise ConfigError(f"--out {out_dir}: exists and is not a folder")
        if not is_synthkit_output(written):
            raise ConfigError(
                f"--out {out_dir}: folder exists and is not a synthkit output (no {MARKER} and report.json); "
                "refusing to replace it"
            )
        if not overwrite:
            raise ConfigError(f"--out {out_dir}: output folder exists; pass --overwrite to replace it")
    return written


@contextlib.contextmanager
def target_lock(target: Path) -> Iterator[None]:
    """Hold ``.NAME.lock`` beside ``target`` for the whole run; refuse when another run holds it."""
    lock_path = target.parent / f".{target.name}.lock"
    while True:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES):
                raise ConfigError(f"--out {target}: another synthkit run is writing this folder") from None
            raise
        try:
            same = os.fstat(fd).st_ino == os.stat(lock_path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # the holder removed the file between our open and our lock: take the new one
    try:
        yield
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(lock_path)
        os.close(fd)


def _marker_text() -> str:
    return json.dumps({"synthkit": __version__, "host": socket.gethostname(), "pid": os.getpid()}) + "\n"


def _gone(marker: Path) -> bool:
    """Whether the run that wrote ``marker`` was on this host and its process no longer exists."""
    try:
        info = json.loads(marker.read_text())
        pid, host = int(info["pid"]), str(info["host"])
    except (OSError, ValueError, KeyError, TypeError):
        return False
    if host != socket.gethostname() or pid == os.getpid():
        return False
    return _pid_gone(pid)


def _pid_gone(pid: int) -> bool:
    """Whether no process ``pid`` runs on this host: none exists, or it is a zombie (killed, not yet
    reaped by its parent: a Dask nanny reaps a killed worker a moment later, and a batch cleaning
    the worker's staging folder must not wait for that)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (PermissionError, OverflowError):
        return False
    try:
        stat_line = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat_line.rsplit(")", 1)[-1].split()[:1] == ["Z"]


def remove_leftovers(target: Path) -> list[Path]:
    """Remove ``.NAME.partial-PID`` / ``.NAME.old-PID`` folders beside ``target`` whose run is gone
    (only folders holding our marker); return what was removed."""
    removed = []
    for kind in _LEFTOVER_KINDS:
        for folder in target.parent.glob(f".{target.name}.{kind}-*"):
            if not folder.is_dir() or folder.is_symlink():
                continue
            if _gone(folder / MARKER):
                shutil.rmtree(folder, ignore_errors=True)
                removed.append(folder)
            elif kind == "partial" and _remove_if_unstarted(folder):
                removed.append(folder)
    return removed


def _remove_if_unstarted(folder: Path) -> bool:
    """Remove a staging folder ``.NAME.partial-PID`` whose run was killed between creating it and
    writing its marker: empty, or holding only an empty marker file, and PID (from the name) no
    longer a process here. Called under the target's lock, so no live run is creating it; a folder
    holding anything else, or named for a live process, is kept."""
    try:
        pid = int(folder.name.rsplit("-", 1)[1])
    except ValueError:
        return False
    if pid == os.getpid() or not _pid_gone(pid):
        return False
    entries = list(folder.iterdir())
    if any(e.name != MARKER or e.is_symlink() or not e.is_file() or e.stat().st_size for e in entries):
        return False
    try:
        for e in entries:
            e.unlink()
        folder.rmdir()
    except OSError:
        return False
    return True


def staging_path(target: Path) -> Path:
    """The hidden staging folder of this process for ``target``: ``.NAME.partial-PID`` beside it."""
    return target.parent / f".{target.name}.partial-{os.getpid()}"


def clear_staging(staging: Path, target: Path) -> None:
    """Remove an earlier ``staging`` of this pid (a reused pid); refuse one that is not ours."""
    if staging.exists() or staging.is_symlink():
        if staging.is_symlink() or not (staging / MARKER).is_file():
            raise ConfigError(f"--out {target}: {staging} exists and is not a synthkit staging folder")
        shutil.rmtree(staging)


def make_staging(staging: Path) -> None:
    """Create ``staging`` (see :func:`staging_path`) with the marker inside. Call it inside the block
    that removes ``staging`` on any exception, so that a signal arriving here leaves nothing."""
    staging.mkdir()
    (staging / MARKER).write_text(_marker_text())


def move_into_place(staging: Path, target: Path, *, overwrite: bool) -> None:
    """Rename ``staging`` to ``target``. An existing target is replaced only with ``overwrite`` and
    only when it is a synthkit output; without it, a target that appeared meanwhile is refused."""
    (staging / MARKER).write_text(_marker_text())
    if target.exists() or target.is_symlink():
        if not overwrite or not target.is_dir() or target.is_symlink() or not is_synthkit_output(target):
            raise ConfigError(f"--out {target}: output folder appeared during the run; not replaced")
        old = target.parent / f".{target.name}.old-{os.getpid()}"
        os.rename(target, old)
        os.rename(staging, target)
        shutil.rmtree(old, ignore_errors=True)
        return
    try:
        os.rename(staging, target)
    except OSError as exc:
        if exc.errno in (errno.ENOTEMPTY, errno.EEXIST, errno.EISDIR, errno.ENOTDIR):
            raise ConfigError(f"--out {target}: output folder appeared during the run; not replaced") from None
        raise


__all__ = [
    "MARKER",
    "check_target",
    "inside",
    "is_synthkit_output",
    "clear_staging",
    "make_staging",
    "staging_path",
    "move_into_place",
    "output_name",
    "remove_leftovers",
    "target_lock",
]
