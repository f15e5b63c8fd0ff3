"""The one error the reshape stages raise: a ValueError naming the config key at fault.

Stage modules take arrays and options and know no exit codes; the pipeline maps a
:class:`StageError` to :class:`~synthkit.errors.ConfigError` (``key: message``) when ``key`` is set,
else to :class:`~synthkit.errors.InputError` (the message names the file).
"""

from __future__ import annotations

__all__ = ["StageError"]


class StageError(ValueError):
    """A stage cannot do what it was asked; ``key`` is the config key whose value is at fault
    (``"chain[0].b_portal"``), None when the input is."""

    def __init__(self, message: str, key: str | None = None):
        super().__init__(message)
        self.key = key
