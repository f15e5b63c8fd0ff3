from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from synthkit.errors import InputError
from synthkit.io.images import save_image
from synthkit.result import Result, result_fields


@dataclass(kw_only=True)
class EchoResult(Result):
    """The echo method's result in memory: ``image (H, W) float32``, written as output ``key``."""

    method: ClassVar[str] = "echo"
    image: np.ndarray
    key: str = "image"
    filename: str = "result.png"

    def write(self, ctx):
        save_image(ctx.path(self.key, self.filename), self.image)


def compute(cfg, inputs, ctx):
    """Copy or invert the image; ``fail`` refuses, refuses with a diagnostic kept, crashes or
    degrades on purpose."""
    name = "image" if inputs.is_memory(cfg.image) else cfg.image
    with ctx.stage("load"):
        img = inputs.image(cfg.image, mode="gray")
    if cfg.fail == "input":
        raise InputError(f"{name}: deliberately refused")
    if cfg.fail == "refuse":
        ctx.metrics["why"] = "statistics kept"
        ctx.metrics["ratio"] = float("nan")
        kept = EchoResult(image=img, key="diagnostic", filename="diagnostic.png", **result_fields(cfg, ctx, inputs))
        raise InputError(f"{name}: refused after writing diagnostics", keep_outputs=True, result=kept)
    if cfg.fail == "crash":
        raise ZeroDivisionError("deliberate crash")
    with ctx.stage("process"):
        out = np.clip((1.0 - img if cfg.mode == "invert" else img) * cfg.gain, 0.0, 1.0)
        noise = ctx.rng.integers(0, 1000)
    if cfg.fail == "degrade":
        ctx.check_quality("mesh", {"open_edges": 4}, {"open_edges": 9}, {"open_edges": 8})
    ctx.metrics["mean"] = float(out.mean())
    ctx.metrics["noise"] = int(noise)
    return EchoResult(image=out, **result_fields(cfg, ctx, inputs))
