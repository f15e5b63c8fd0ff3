from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from synthkit.api import Result, result_fields
from synthkit.errors import InputError
from synthkit.io.images import load_image, save_image


def run(cfg, ctx):
    with ctx.stage("load"):
        img = load_image(cfg.image, mode="gray")
    if cfg.fail == "input":
        raise InputError(f"{cfg.image}: deliberately refused")
    if cfg.fail == "refuse":
        ctx.metrics["why"] = "statistics kept"
        ctx.metrics["ratio"] = float("nan")
        save_image(ctx.path("diagnostic", "diagnostic.png"), img)
        raise InputError(f"{cfg.image}: refused after writing diagnostics", keep_outputs=True)
    if cfg.fail == "crash":
        raise ZeroDivisionError("deliberate crash")
    with ctx.stage("process"):
        out = 1.0 - img if cfg.mode == "invert" else img
        out = np.clip(out * cfg.gain, 0.0, 1.0)
        noise = ctx.rng.integers(0, 1000)
    save_image(ctx.path("image", "result.png"), out)
    if cfg.fail == "degrade":
        ctx.check_quality("mesh", {"open_edges": 4}, {"open_edges": 9}, {"open_edges": 8})
    ctx.metrics["mean"] = float(out.mean())
    ctx.metrics["noise"] = noise


@dataclass(kw_only=True)
class EchoResult(Result):
    """The echo method's result in memory: ``image (H, W) float32``."""

    method: ClassVar[str] = "echo"
    image: np.ndarray

    def write(self, ctx):
        save_image(ctx.path("image", "result.png"), self.image)


def compute(cfg, inputs, ctx):
    """The in-memory form of :func:`run` (no refusal with diagnostics)."""
    with ctx.stage("load"):
        img = inputs.image(cfg.image, mode="gray")
    if cfg.fail == "input":
        raise InputError("image: deliberately refused")
    with ctx.stage("process"):
        out = np.clip((1.0 - img if cfg.mode == "invert" else img) * cfg.gain, 0.0, 1.0)
    ctx.metrics["mean"] = float(out.mean())
    return EchoResult(image=out, **result_fields(cfg, ctx, inputs))
