"""The stage line on a terminal: silent for short stages, elapsed seconds for long ones, cleared."""

import io
import time

from synthkit.progress import StageTicker


def test_short_stage_prints_nothing():
    out = io.StringIO()
    with StageTicker(out, "run: load", delay=0.5, interval=0.05):
        time.sleep(0.05)
    assert out.getvalue() == ""


def test_long_stage_shows_elapsed_then_clears():
    out = io.StringIO()
    with StageTicker(out, "run: solve", delay=0.05, interval=0.05):
        time.sleep(0.3)
    text = out.getvalue()
    assert "\rrun: solve 0 s" in text
    assert text.endswith("\r" + " " * len("run: solve 0 s") + "\r")


def test_silent_while_a_bar_is_open():
    out = io.StringIO()
    with StageTicker(out, "run: solve", busy=lambda: True, delay=0.01, interval=0.01):
        time.sleep(0.1)
    assert out.getvalue() == ""
