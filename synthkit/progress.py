"""A line on a terminal that says which stage of a run is working, once it has taken a while.

:class:`StageTicker` is started by :meth:`synthkit.context.RunContext.stage` when progress is shown
(a terminal, no ``--no-progress`` or ``-q``): after :data:`TICK_DELAY` seconds it writes
``<method>: <stage> 12 s`` on stderr and rewrites it every :data:`TICK_INTERVAL`, and clears the
line when the stage ends. While a stage shows its own progress bar, the ticker stays silent.
"""

from __future__ import annotations

import threading
import time
from typing import TextIO

__all__ = ["StageTicker", "TICK_DELAY", "TICK_INTERVAL"]

TICK_DELAY = 2.0
"""Seconds a stage runs before its line appears (shorter stages print nothing)."""

TICK_INTERVAL = 0.5
"""Seconds between rewrites of the line."""


class StageTicker:
    """Context manager: a background thread showing ``label: stage <seconds> s`` on ``stream``.

    ``busy()`` (a callable) returning True (a progress bar is on screen) keeps it from writing.
    """

    def __init__(self, stream: TextIO, label: str, *, busy=lambda: False, delay: float = TICK_DELAY,
                 interval: float = TICK_INTERVAL):
        self.stream, self.label, self.busy = stream, label, busy
        self.delay, self.interval = delay, interval
        self._stop = threading.Event()
        self._width = 0
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> StageTicker:
        self._start = time.perf_counter()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()
        if self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self.stream.flush()

    def _run(self) -> None:
        if self._stop.wait(self.delay):
            return
        while not self._stop.is_set():
            if not self.busy():
                text = f"{self.label} {time.perf_counter() - self._start:.0f} s"
                self.stream.write("\r" + text.ljust(self._width))
                self.stream.flush()
                self._width = max(self._width, len(text))
            self._stop.wait(self.interval)
