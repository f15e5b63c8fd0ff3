"""Threads of synthkit's own parallel work, in one place: the shared thread pools (one per purpose,
so work a pool runs may submit to another without waiting on itself) and the limit on the BLAS
libraries' own threads while they run."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

from threadpoolctl import ThreadpoolController

__all__ = ["one_blas_thread", "thread_pool"]

_POOLS: dict[tuple[str, int], ThreadPoolExecutor] = {}
_POOLS_LOCK = threading.Lock()


def thread_pool(name: str, threads: int) -> ThreadPoolExecutor:
    """The process's pool ``name`` of ``threads`` workers, made on first use (numpy, scipy.fft and
    numba kernels release the GIL). Each purpose names its own pool: a task of one pool that waits
    for tasks of the same pool could wait for ever."""
    with _POOLS_LOCK:
        if (name, threads) not in _POOLS:
            _POOLS[name, threads] = ThreadPoolExecutor(max_workers=threads, thread_name_prefix=name)
        return _POOLS[name, threads]


_BLAS: ThreadpoolController | None = None
_BLAS_DEPTH = 0


@contextmanager
def one_blas_thread():
    """Context: the BLAS libraries loaded (numpy's and scipy's OpenBLAS) run on one thread, and
    get their thread counts back on exit (process-wide: entered by the calling thread only, around
    work whose helper threads it waits for; nested entries cost nothing).

    The spectral evaluation's products are a few milliseconds each; OpenBLAS's own threads, on a
    machine shared with other work, then wait for a core more than they compute (measured: a 512
    sweep at window 0.5 took 30 s with them and 12 s without). Work is shared by our threads instead."""
    global _BLAS, _BLAS_DEPTH
    if _BLAS_DEPTH:
        _BLAS_DEPTH += 1
        try:
            yield
        finally:
            _BLAS_DEPTH -= 1
        return
    if _BLAS is None:
        _BLAS = ThreadpoolController()
    with _BLAS.limit(limits=1, user_api="blas"):
        _BLAS_DEPTH = 1
        try:
            yield
        finally:
            _BLAS_DEPTH = 0
