"""What a method run gives back (:class:`Result`, each method's outputs in memory with its metrics,
timings and status) and the fields every method fills from its run's context. Below the runner and
the Python functions (:mod:`synthkit.api`): methods build their results here."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from synthkit.config import RunConfig
from synthkit.context import save_result
from synthkit.io.inputs import Inputs

__all__ = ["Result", "result_fields"]


@dataclass(kw_only=True)
class Result(ABC):
    """What a method run in memory gives back; each method's subclass adds its outputs.

    Attributes
    ----------
    config : the validated config (every key with its default filled in)
    metrics : what ``report.json`` holds under ``metrics``
    timings : seconds per stage, with ``total``
    status : ``"ok"``, ``"degraded"`` (an output mesh over its quality limits, see
        ``quality_warnings``) or ``"partial"``
    quality_warnings : one line per quality figure over its limit
    input_files : the files the run read (a later :meth:`save` never writes over them)
    """

    method: ClassVar[str] = ""
    config: RunConfig
    metrics: dict[str, Any] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    status: str = "ok"
    quality_warnings: list[str] = field(default_factory=list)
    input_files: list[Path] = field(default_factory=list)

    @abstractmethod
    def write(self, ctx) -> None:
        """Write the output files and previews through ``ctx.path`` (a
        :class:`synthkit.context.RunContext` with a staging folder); each method implements it."""

    def save(self, folder: Path | str, *, overwrite: bool = False, previews: str = "all") -> dict[str, Any]:
        """Write the outputs into ``folder`` as the command line writes them, with ``report.json``;
        return the report. The folder is written whole or not at all; an existing folder is replaced
        only with ``overwrite`` and only when a synthkit run wrote it.

        Parameters
        ----------
        folder : the output folder
        overwrite : replace an earlier synthkit output folder
        previews : ``"all"``, ``"summary"`` (the one summary image) or ``"none"``
        """
        return save_result(self, folder, overwrite=overwrite, previews=previews)


def result_fields(cfg: RunConfig, ctx, inputs: Inputs | None = None) -> dict[str, Any]:
    """The :class:`Result` fields every method fills the same way, from the run's context."""
    files = [] if inputs is None else list(inputs.files)
    return {"config": cfg, "metrics": ctx.metrics, "timings": ctx.timings, "status": ctx.status,
            "quality_warnings": ctx.quality_warnings, "input_files": files}

