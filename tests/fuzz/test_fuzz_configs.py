"""YAML configs and batch files, mutated (issue 37): every bundled config, and a batch file over
them, is read and validated or refused with one line naming the file (exit 2), within CASE_SECONDS."""

from __future__ import annotations

import time

import pytest
from hypothesis import given
from hypothesis import strategies as st

from synthkit.plan import PlanError, plan_jobs
from synthkit.runner import load_method_config

from .conftest import CASE_SECONDS, RECIPES, REPO

CONFIGS = sorted((REPO / "configs").glob("*/*.yaml"))


def _absolute(config) -> bytes:
    """A bundled config with its sample paths absolute, so that a copy elsewhere names the same files."""
    return config.read_bytes().replace(b"../../data-samples/", f"{REPO / 'data-samples'}/".encode())


def _batch_text() -> bytes:
    configs = "".join(f"  - {c}\n" for c in CONFIGS[:3])
    return f"configs:\n{configs}set:\n  seed: 3\nsweep:\n  preview_size: [64, 96]\n".encode()


def _validated(path, overrides=()):
    return load_method_config(path, overrides=overrides)


@given(config=st.sampled_from(CONFIGS), recipe=RECIPES)
def test_mutated_configs_keep_the_promise(config, recipe, mutate, keeps_promise, tmp_path_factory):
    path = tmp_path_factory.getbasetemp() / "fuzz-config.yaml"
    path.write_bytes(mutate(_absolute(config), recipe))
    start = time.perf_counter()
    keeps_promise(_validated, path)
    assert time.perf_counter() - start < CASE_SECONDS


def _planned(path, out_root):
    try:
        return plan_jobs([str(path)], sweeps=(), overrides=(), seed=None, out_root=str(out_root))[0]
    except PlanError as exc:  # the batch's own rules (a clash of output names): one line, exit 2 at the CLI
        assert "\n" not in str(exc)
        return []


@given(recipe=RECIPES)
def test_mutated_batch_files_keep_the_promise(recipe, mutate, keeps_promise, tmp_path_factory):
    path = tmp_path_factory.getbasetemp() / "fuzz-batch.yaml"
    path.write_bytes(mutate(_batch_text(), recipe))
    start = time.perf_counter()
    jobs = keeps_promise(lambda p: _planned(p, p.parent / "out"), path) or []
    for job in jobs:  # a batch file that is no longer one is run as a config
        keeps_promise(lambda p, job=job: _validated(p, job.overrides), type(path)(job.config))
    assert time.perf_counter() - start < CASE_SECONDS


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: f"{c.parent.name}/{c.name}")
def test_the_unmutated_configs_validate(config, tmp_path):
    path = tmp_path / "config.yaml"
    path.write_bytes(_absolute(config))
    assert _validated(path)[0] == config.parent.name
