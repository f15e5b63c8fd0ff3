"""Running one method on one config: validation, timing, progress, atomic output, report.json.

The output folder is built in a hidden staging folder beside it and renamed into place only when
the run succeeded, so an output folder is always complete or absent. An existing output folder is
replaced only with ``overwrite=True``, only when it is a previous synthkit output, and never when
it holds an input of the run (:mod:`synthkit.outdir`).
"""

from __future__ import annotations

import logging
import os
import shutil
import time
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from synthkit import outdir
from synthkit.config import RunConfig, apply_overrides, load_yaml, validate_config
from synthkit.context import RefusalKept, RunContext, check_previews, staged_output, write_report
from synthkit.errors import ConfigError, QualityError, SynthkitError
from synthkit.io.inputs import Inputs
from synthkit.limits import Budget
from synthkit.methods import METHODS, available_methods
from synthkit.methods.rooms import config_module, pipeline_module
from synthkit.summary import main_output, summary_preview

log = logging.getLogger("synthkit")


def load_method_config(
    config_path: Path,
    *,
    method: str | None = None,
    overrides: Iterable[str] = (),
    seed: int | None = None,
    check_files: bool = True,
    named_inputs: list[Path] | None = None,
    input_fields: list[str] | None = None,
) -> tuple[str, RunConfig, list[Path]]:
    """Load and validate a config file; return (method name, config, resolved input files).

    ``method`` None dispatches on the file's ``method:`` key; otherwise the key must agree (or be
    absent). ``overrides`` are ``key.path=value`` strings; ``seed`` replaces the config's seed.
    ``named_inputs``, when given, receives the input files as the config names them (absolute,
    symbolic links not followed).
    """
    config_path = Path(config_path)
    data = load_yaml(config_path)
    data = apply_overrides(data, overrides)
    declared = data.get("method")
    if method is None:
        if declared is None:
            raise ConfigError(f"{config_path}: missing required key 'method' (one of {', '.join(METHODS)})")
        method = declared
    elif declared is not None and declared != method:
        raise ConfigError(f"{config_path}: method: {declared!r} does not match the subcommand {method!r}")
    if method not in METHODS:
        raise ConfigError(f"{config_path}: method: unknown method {method!r} (one of {', '.join(METHODS)})")
    if method not in available_methods():
        raise ConfigError(f"{config_path}: method: {method!r} is not implemented in this version")
    data["method"] = method
    if seed is not None:
        data["seed"] = seed
    inputs: list[Path] = []
    model = config_module(method).CONFIG
    cfg = validate_config(
        model,
        data,
        source=config_path,
        base_dir=config_path.resolve().parent,
        check_files=check_files,
        inputs=inputs,
        named_inputs=named_inputs,
        input_fields=input_fields,
    )
    return method, cfg, inputs


IMAGE_BYTES_PER_PIXEL = 32
"""Bytes an input image costs per pixel before any method works on it: the decoded 8-bit file,
its float32 RGB copy and one working copy."""

MESH_BYTES_PER_FACE = 256
"""Bytes an input mesh costs per triangle once loaded: float64 positions and int64 faces with the
adjacency and per-face caches trimesh builds."""


def check_input_sizes(inputs: list[Path], fields: list[str], budget: Budget) -> None:
    """Refuse (ConfigError naming the config key and the file, exit 2) an input image or mesh whose
    header says it cannot fit the run's budget, before anything is decoded (:mod:`synthkit.io.probe`).
    ``fields`` names the key of each of ``inputs``."""
    from synthkit.io.images import IMAGE_SUFFIXES
    from synthkit.io.meshes import MESH_SUFFIXES
    from synthkit.io.probe import image_shape, mesh_face_count

    for path, key in zip(inputs, fields, strict=True):
        suffix = path.suffix.lower()
        if suffix in IMAGE_SUFFIXES:
            shape = image_shape(path)
            if shape is not None:
                budget.require(key, f"{path} ({shape[1]}x{shape[0]})", float(shape[0]) * shape[1], "pixels",
                               bytes_each=IMAGE_BYTES_PER_PIXEL)
        elif suffix in MESH_SUFFIXES:
            faces = mesh_face_count(path)
            if faces is not None:
                budget.require(key, f"{path} ({faces} faces)", faces, "faces", bytes_each=MESH_BYTES_PER_FACE)


def default_out_dir(config_path: Path, out_root: Path | str = "out") -> Path:
    """``<out_root>/<config file stem>``; refuses stems that are not a plain folder name."""
    out_root = Path(out_root)
    target = out_root / outdir.output_name(config_path)
    if not outdir.inside(target, out_root):
        raise ConfigError(f"{config_path}: output folder {target} would lie outside {out_root}")
    return target


def _naming_config(exc: SynthkitError, config_path: Path) -> SynthkitError:
    """``exc``, or the same error class with its line prefixed by ``config_path`` when the line does
    not name the config already (a pipeline names the key and value; the runner adds the file)."""
    line = str(exc)
    if line.startswith(str(config_path)):
        return exc
    return type(exc)(f"{config_path}: {line}", keep_outputs=exc.keep_outputs)


@dataclass(frozen=True)
class RunSettings:
    """How runs are carried out, the same for every run of one command, apart from each config.

    Built once by the command line from its options (``cli/options.py``), passed whole to
    :func:`run_config` and, for a batch, to :func:`synthkit.batch.execute` here or on a Dask worker.

    Attributes
    ----------
    seed : int or None
        Replaces every config's ``seed`` (``--seed``); None keeps each config's own.
    overwrite : bool
        Replace an output folder that a previous synthkit run wrote (``--overwrite``).
    show_progress : bool
        Stage lines and progress bars on a terminal.
    max_bytes : int or None
        Memory budget of each run (``--max-memory``); None: :func:`synthkit.limits.default_max_bytes`
        of the machine that runs it.
    previews : str
        ``"all"``, ``"summary"`` or ``"none"`` (``--previews``).
    strict : bool
        ``--strict``: a degraded output raises :class:`QualityError` (exit 3) once written, and a
        pipeline refuses what it would otherwise only warn about.
    name_outputs : bool
        ``--name-outputs``: the summary preview and main result are also linked under the folder's name.
    verbosity : int
        -1 quiet, 0 normal, 1 verbose, 2 debug: the logging of a run on a Dask worker.
    """

    seed: int | None = None
    overwrite: bool = False
    show_progress: bool = True
    max_bytes: int | None = None
    previews: str = "all"
    strict: bool = False
    name_outputs: bool = False
    verbosity: int = 0


def run_config(
    config_path: Path,
    *,
    method: str | None = None,
    out_dir: Path | None = None,
    overrides: Iterable[str] = (),
    settings: RunSettings | None = None,
    **changes: Any,
) -> dict[str, Any]:
    """Validate ``config_path``, run its method into ``out_dir`` atomically and return the report.

    ``settings`` (default :class:`RunSettings`) with ``changes`` to its fields, as keywords
    (``run_config(path, show_progress=False)``). See :mod:`synthkit.outdir` for what may be
    replaced, the lock and the staging folder. With ``strict``, a run whose report says
    ``degraded`` is written, then raises :class:`QualityError` (exit 3) naming its first figure over
    a limit. With ``name_outputs``, the summary preview and the main result are also written as
    ``<folder name>.<suffix>`` and ``<folder name>.preview.png`` (hard links), so that files
    gathered from many runs keep apart.
    """
    s = replace(settings or RunSettings(), **changes)
    named: list[Path] = []
    fields: list[str] = []
    method, cfg, inputs = load_method_config(
        config_path, method=method, overrides=overrides, seed=s.seed, named_inputs=named, input_fields=fields
    )
    budget = Budget(s.max_bytes)
    check_input_sizes(inputs, fields, budget)
    out_dir = Path(out_dir) if out_dir is not None else default_out_dir(config_path)
    config_forms = [Path(os.path.abspath(config_path)), Path(config_path).resolve()]
    with staged_output(out_dir, [*named, *inputs, *config_forms], overwrite=s.overwrite) as staging:
        ctx = RunContext(staging, seed=cfg.seed, show_progress=s.show_progress, budget=budget, previews=s.previews,
                         strict=s.strict)
        name = Path(os.path.abspath(out_dir)).name
        ctx.label = f"{method} {name}"
        ctx.name_outputs_as = name if s.name_outputs else None
        report = _run_staged(method, cfg, ctx, config_path)
    log.info("%s: wrote %s (%.2f s)", method, out_dir, ctx.timings["total"])
    if s.strict and report["status"] == "degraded":
        raise QualityError(f"{config_path}: output degraded (--strict): {ctx.quality_warnings[0]}")
    return report


def _run_staged(method: str, cfg: RunConfig, ctx: RunContext, config_path: Path) -> dict[str, Any]:
    """Run the pipeline into ``ctx.out_dir`` and write report.json there; return the report.

    A refusal that keeps its outputs (``keep_outputs``) writes its report with ``status: refused``
    and comes out as :class:`RefusalKept`, so that the caller moves the folder into place before
    raising the refusal itself."""
    start = time.perf_counter()
    try:
        _compute_and_write(method, cfg, ctx)
        if ctx.name_outputs_as:
            _name_outputs(ctx, method, ctx.name_outputs_as)
        check_previews(method, ctx)
        return write_report(method, cfg, ctx, config_path, start, ctx.status)
    except SynthkitError as exc:
        named = _naming_config(exc, config_path)
        if named.keep_outputs:
            write_report(method, cfg, ctx, config_path, start, "refused", str(named))
            raise RefusalKept(named) from None
        if named is exc:
            raise
        raise named from None


def _compute_and_write(method: str, cfg: RunConfig, ctx: RunContext) -> None:
    """The method's ``compute`` on the config's files, then its result's files; a refusal's partial
    result (``exc.result``) is written before the refusal is raised."""
    try:
        result = pipeline_module(method).compute(cfg, Inputs(), ctx)
    except SynthkitError as exc:
        if exc.result is not None:
            exc.result.write(ctx)
        raise
    result.write(ctx)


def _name_outputs(ctx: RunContext, method: str, name: str) -> None:
    """Hard-link (or copy) the summary preview and the main result under the run's ``name``."""
    for key, source in (
        ("named_preview", summary_preview(ctx.outputs, method)),
        ("named_result", main_output(ctx.outputs, method)),
    ):
        if source is None:
            continue
        suffix = ".preview.png" if key == "named_preview" else Path(source).suffix
        target = ctx.path(key, f"{name}{suffix}")
        try:
            os.link(ctx.out_dir / source, target)
        except OSError:
            shutil.copyfile(ctx.out_dir / source, target)


__all__ = ["RunSettings", "run_config", "load_method_config", "default_out_dir", "check_input_sizes"]
