"""Planning a batch: parameter sweeps, batch files, output folder names and the jobs they make.

``synthkit run`` plans here (:func:`plan_jobs`: configs, batch files and sweeps into :class:`Job` s,
with the notes a user should read) and runs the jobs with :mod:`synthkit.batch`, in its own process
or on Dask (:mod:`synthkit.cluster`). Nothing here imports Dask or runs a method.
"""

from __future__ import annotations

import difflib
import hashlib
import itertools
import json
import math
import os
import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from synthkit.errors import ConfigError

MAX_NAME = 120
"""Longest output folder name from a sweep; longer names are cut and end with a hash of the whole."""
_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*(\.[A-Za-z0-9_-]+)*$")
_RANGE = re.compile(r"^(-?\d+)\.\.(-?\d+)$")
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


# ---------------------------------------------------------------------------------------- sweeps

def split_values(text: str) -> list[str]:
    """Split ``text`` at the commas that are not inside brackets, braces or quotes.

    >>> split_values("1,[2, 3],'a,b'")
    ['1', '[2, 3]', "'a,b'"]
    """
    parts, depth, quote, start = [], 0, None, 0
    for i, ch in enumerate(text):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return [p.strip() for p in parts]


def expand_values(values: Iterable[str]) -> list[str]:
    """Each value as written, with integer ranges ``a..b`` (both ends included) spelt out."""
    out: list[str] = []
    for value in values:
        match = _RANGE.match(value)
        if match:
            lo, hi = int(match.group(1)), int(match.group(2))
            if hi < lo:
                raise ValueError(f"range {value} is empty (write the smaller end first)")
            if hi - lo >= 10_000:
                raise ValueError(f"range {value} has more than 10000 values")
            out.extend(str(v) for v in range(lo, hi + 1))
        else:
            out.append(value)
    return out


def parse_sweep(text: str) -> tuple[str, list[str]]:
    """``"key.path=v1,v2,a..b"`` -> ``("key.path", ["v1", "v2", "a", ..., "b"])``.

    Values are YAML, as with ``--set``; each is kept as written (it names the folder). Raises
    ValueError with the reason.
    """
    key, sep, rest = text.partition("=")
    key = key.strip()
    if not sep or not _KEY.match(key):
        raise ValueError(f"{text!r} is not KEY.PATH=V1,V2,... (e.g. seed=0..9 or synth.patch=16,24)")
    values = split_values(rest)
    if any(v == "" for v in values):
        raise ValueError(f"{text!r} has an empty value")
    values = expand_values(values)
    if len(set(values)) != len(values):
        raise ValueError(f"{text!r} repeats a value")
    return key, values


def sweep_axes(specs: Iterable[str]) -> list[tuple[str, list[str]]]:
    """Parse every ``--sweep`` text; a key may be swept only once."""
    axes: list[tuple[str, list[str]]] = []
    for spec in specs:
        key, values = parse_sweep(spec)
        if any(key == k for k, _ in axes):
            raise ValueError(f"{key} is swept twice; give all its values in one --sweep")
        axes.append((key, values))
    return axes


MAX_BATCH_RUNS = 100_000
"""Most runs one ``synthkit run`` may plan (configs times sweep combinations); counted before any
combination is built."""


def config_method(path: str) -> str | None:
    """The ``method:`` a config file declares, or None when it cannot be read (the run reports why)."""
    from synthkit.config import load_yaml
    from synthkit.errors import SynthkitError

    try:
        method = load_yaml(Path(path)).get("method")
    except SynthkitError:
        return None
    return method if isinstance(method, str) else None


def axes_for(method: str | None, axes: Sequence[tuple[str, Sequence[str]]]):
    """Split sweep ``axes`` into those whose key ``method``'s schema has and those it lacks (a
    batch may mix methods: a sweep key applies where it means something). An unknown method keeps
    every axis, so that its run reports the problem."""
    from synthkit.config import schema_has_key
    from synthkit.methods import METHODS
    from synthkit.methods.rooms import config_module

    if method not in METHODS:
        return list(axes), []
    model = config_module(method).CONFIG
    kept = [(k, v) for k, v in axes if schema_has_key(model, k)]
    return kept, [k for k, _ in axes if not schema_has_key(model, k)]




def count_runs(axes: Sequence[tuple[str, Sequence[str]]]) -> int:
    """How many combinations :func:`combinations` yields (1 without axes)."""
    return math.prod(len(v) for _, v in axes)


def combinations(axes: Sequence[tuple[str, Sequence[str]]]) -> Iterator[dict[str, str]]:
    """The Cartesian product of the axes, lazily, the first axis varying slowest; one ``{}`` without axes."""
    keys = [k for k, _ in axes]
    return (dict(zip(keys, combo, strict=True)) for combo in itertools.product(*(v for _, v in axes)))


def sanitise(text: str) -> str:
    """``text`` with every run of characters outside ``[A-Za-z0-9._-]`` replaced by ``_``."""
    return _UNSAFE.sub("_", text).strip("_") or "_"


def folder_name(stem: str, sweep: dict[str, str]) -> str:
    """The output folder name of one sweep combination: ``stem__key-value__key-value``.

    >>> folder_name("facade", {"seed": "3", "analysis.dense_radius": "0.03"})
    'facade__seed-3__analysis.dense_radius-0.03'
    """
    name = stem + "".join(f"__{sanitise(k)}-{sanitise(v)}" for k, v in sweep.items())
    if len(name) > MAX_NAME:
        digest = hashlib.sha1(name.encode()).hexdigest()[:10]
        name = f"{name[: MAX_NAME - 11]}-{digest}"
    return name


def sweep_overrides(sweep: dict[str, str]) -> list[str]:
    """The ``--set`` overrides of one combination."""
    return [f"{k}={v}" for k, v in sweep.items()]


# ----------------------------------------------------------------------------------- batch files

BATCH_KEYS = ("configs", "set", "sweep")
"""Top-level keys of a batch file (a YAML file with ``configs:`` and no ``method:``)."""


@dataclass
class BatchFile:
    """A batch file: configs (paths relative to the file), ``set:`` overrides and ``sweep:`` axes."""

    path: str
    configs: list[str]
    overrides: list[str]
    axes: list[tuple[str, list[str]]]


def _yaml_text(value: Any) -> str:
    """``value`` as YAML text for an override: a string as written when it reads back as itself,
    anything else as JSON (which is YAML)."""
    import yaml

    if isinstance(value, str):
        try:
            if yaml.safe_load(value) == value:
                return value
        except yaml.YAMLError:
            pass
    return json.dumps(value)


def read_batch_file(path: str) -> BatchFile | None:
    """The batch file at ``path``, or None when ``path`` is not one (a config, or not readable:
    the run then reports that as for any config).

    A batch file is a YAML mapping with ``configs:`` (a list of config files, relative to the batch
    file) and no ``method:``; optional ``set:`` maps ``key.path`` to a value (as ``--set``) and
    ``sweep:`` maps ``key.path`` to a list of values or a range string ``"A..B"`` (as ``--sweep``).
    Raises ConfigError naming the file and the key for a malformed one.
    """
    from synthkit.config import load_yaml
    from synthkit.errors import SynthkitError

    try:
        data = load_yaml(Path(path))
    except SynthkitError:
        return None
    if "configs" not in data or "method" in data:
        return None
    unknown = sorted(set(data) - set(BATCH_KEYS))
    if unknown:
        close = difflib.get_close_matches(unknown[0], BATCH_KEYS, n=1)
        hint = f"did you mean {close[0]!r}?" if close else f"keys: {', '.join(BATCH_KEYS)}"
        raise ConfigError(f"{path}: unknown key {unknown[0]!r} in a batch file ({hint})")
    configs, overrides, sweep = data["configs"], data.get("set") or {}, data.get("sweep") or {}
    if not isinstance(configs, list) or not configs or not all(isinstance(c, str) and c for c in configs):
        raise ConfigError(f"{path}: configs: expected a list of config file paths")
    for key, value in (("set", overrides), ("sweep", sweep)):
        if not isinstance(value, dict) or not all(isinstance(k, str) and _KEY.match(k) for k in value):
            raise ConfigError(f"{path}: {key}: expected a mapping of key.path to values")
    axes = []
    for key, values in sweep.items():
        if isinstance(values, str):
            values = split_values(values)
        elif isinstance(values, list) and values:
            values = [v if isinstance(v, str) else _yaml_text(v) for v in values]  # strings as on the command line
        else:
            raise ConfigError(f"{path}: sweep.{key}: expected a list of values or a range such as 0..9")
        try:
            axes.append((key, expand_values(values)))
        except ValueError as exc:
            raise ConfigError(f"{path}: sweep.{key}: {exc}") from None
        if len(set(axes[-1][1])) != len(axes[-1][1]):
            raise ConfigError(f"{path}: sweep.{key}: repeats a value")
    base = Path(path).parent
    return BatchFile(path=str(path), configs=[str(base / c) if not os.path.isabs(c) else c for c in configs],
                     overrides=[f"{k}={_yaml_text(v)}" for k, v in overrides.items()], axes=axes)


# ------------------------------------------------------------------------------------------ jobs

@dataclass
class Job:
    """One run of a batch: a config, its overrides (batch file ``set:``, ``--set``, then the sweep's,
    all in ``overrides``; the first two also in ``set_overrides``) and its output folder."""

    config: str
    overrides: list[str]
    sweep: dict[str, str] = field(default_factory=dict)
    set_overrides: list[str] = field(default_factory=list)
    out: str | None = None


# -------------------------------------------------------------------------------------- planning

class PlanError(ValueError):
    """A batch that cannot be planned; ``option`` names the command-line option at fault (or None)."""

    def __init__(self, message: str, option: str | None = None):
        super().__init__(message)
        self.option = option


def _entries(configs: Sequence[str]) -> list[tuple[str, list[str], list]]:
    """(config, batch-file overrides, batch-file sweep axes) of every config, batch files expanded."""
    entries = []
    for path in configs:
        spec = read_batch_file(path)  # ConfigError for a malformed batch file
        entries.extend([(c, spec.overrides, spec.axes) for c in spec.configs] if spec else [(path, [], [])])
    return entries


def plan_jobs(configs: Sequence[str], *, sweeps: Sequence[str], overrides: Sequence[str], seed: int | None,
              out_root: str) -> tuple[list[Job], list[str]]:
    """The jobs of a batch and the notes to show (a sweep key a config's method lacks).

    Raises PlanError (a sweep given twice or with --seed, too many runs, clashing output names)
    or ConfigError (a malformed batch file)."""
    try:
        axes = sweep_axes(sweeps)
    except ValueError as exc:
        raise PlanError(str(exc), "--sweep") from None
    entries = _entries(configs)
    for _, _, file_axes in entries:
        twice = sorted({k for k, _ in file_axes} & {k for k, _ in axes})
        if twice:
            raise PlanError(f"{twice[0]} is swept by a batch file too", "--sweep")
    if seed is not None and any(key == "seed" for _, _, a in entries for key, _ in [*a, *axes]):
        raise PlanError("--seed and --sweep seed=... both set the seed; give one", "--sweep")
    plans, notes = [], []
    for path, base, file_axes in entries:
        kept, dropped = axes_for(config_method(path), [*file_axes, *axes])
        if dropped:
            notes.append(f"note: {path} has no key {', '.join(dropped)}; it runs once for that sweep")
        plans.append((path, base, kept))
    planned = sum(count_runs(kept) for _, _, kept in plans)
    if planned > MAX_BATCH_RUNS:
        raise PlanError(f"the configs and sweeps make {planned} runs; the limit is {MAX_BATCH_RUNS}", "--sweep")
    jobs = [Job(path, [*base, *overrides, *sweep_overrides(combo)], combo, set_overrides=[*base, *overrides])
            for path, base, kept in plans for combo in combinations(kept)]
    names = [folder_name(Path(job.config).stem, job.sweep) for job in jobs]
    clashes = sorted({s for s in names if names.count(s) > 1})
    if clashes:
        raise PlanError(f"configs share output names under {out_root}: {', '.join(clashes)}")
    return jobs, notes


def out_dir_of(job: Job, out_root: str) -> Path:
    """The output folder of ``job``: ``default_out_dir`` without a sweep, the sweep's name beside it."""
    from synthkit import outdir
    from synthkit.runner import default_out_dir

    if not job.sweep:
        return default_out_dir(job.config, out_root)
    target = Path(out_root) / folder_name(outdir.output_name(job.config), job.sweep)
    if not outdir.inside(target, Path(out_root)):
        raise ConfigError(f"{job.config}: output folder {target} would lie outside {out_root}")
    return target
