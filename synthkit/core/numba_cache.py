"""numba's settings for every synthkit kernel, made once on import: whether the kernels keep
numba's on-disk cache (:data:`NUMBA_CACHE`, a usable cache folder chosen where needed) and the
threading layer of parallel kernels."""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

import numba

__all__ = ["NUMBA_CACHE"]


def _numba_cache_usable() -> bool:
    """Whether synthkit's numba kernels can keep numba's
    on-disk cache (``cache=True``); makes sure they can where possible.

    numba caches beside the sources (``__pycache__``), else in ``$XDG_CACHE_HOME/numba``
    (``~/.cache/numba``), or first in ``NUMBA_CACHE_DIR`` when that is set. A read-only install
    falls back to the user's cache silently. When none of these is writable (a read-only
    site-packages and a read-only home, as in some containers and services), numba refuses to
    decorate a ``cache=True`` function with a RuntimeError. Then numba's cache folder is set to
    ``<tempdir>/synthkit-numba-<uid>``, created mode 0700 and used only if it is this user's own and
    writable by no one else (numba's cache files are pickles); failing that, the kernels are
    compiled in each process (no cache).
    """
    try:
        from numba.core.caching import FunctionCache

        FunctionCache(_numba_cache_usable)
        return True
    except RuntimeError:
        pass
    except Exception:  # numba's internals moved: leave caching to numba, as cache=True does
        return True
    uid = os.getuid() if hasattr(os, "getuid") else None
    folder = Path(tempfile.gettempdir()) / f"synthkit-numba-{uid if uid is not None else 'user'}"
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        info = folder.lstat()
        if not stat.S_ISDIR(info.st_mode) or info.st_mode & 0o022 or (uid is not None and info.st_uid != uid):
            return False
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    numba.config.CACHE_DIR = str(folder)
    return True


NUMBA_CACHE = _numba_cache_usable()
"""``cache=`` of every numba kernel in synthkit (see :func:`_numba_cache_usable`)."""

os.environ.setdefault("NUMBA_THREADING_LAYER_PRIORITY", "omp workqueue tbb")
numba.config.THREADING_LAYER_PRIORITY = os.environ["NUMBA_THREADING_LAYER_PRIORITY"].split()
"""Parallel kernels (``parallel=True``) run on OpenMP, else numba's own workqueue, unless the user's
environment says otherwise: numba tries TBB first by default, and pymeshlab ships an older libtbb
that, once pymeshlab is imported, makes numba warn that "the TBB threading layer is disabled" on the
first parallel compile. The environment variable, not only numba's config, carries the choice:
numba reloads its config from the environment whenever the environment changed (a batch sets
thread counts), which would put TBB first again."""
