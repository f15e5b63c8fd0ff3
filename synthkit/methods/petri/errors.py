"""The one exception petri-synth's stage modules raise for a value they refuse."""

from __future__ import annotations

__all__ = ["KeyedError"]


class KeyedError(ValueError):
    """A value a stage refuses. ``key`` names it within its config section (``"unit"``,
    ``"annotation.rect"``, ``"points"``, ``"curves[1]"``); the message reads after ``<section>.<key>: ``.
    :mod:`synthkit.methods.petri.pipeline` turns it into the user's error line and exit code."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key
