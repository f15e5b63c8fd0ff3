from typing import Literal

from pydantic import Field

from synthkit.config import InputFile, RunConfig, StrictModel


class Filter(StrictModel):
    sigma: float = Field(1.0, ge=0.0, description="Blur sigma in pixels.")


class EchoConfig(RunConfig):
    method: Literal["echo"] = "echo"
    image: InputFile = Field(description="Input image.")
    mode: Literal["copy", "invert"] = Field("copy", description="What to do with the image.")
    gain: float = Field(1.0, gt=0.0, le=10.0, description="Multiplier.")
    fail: Literal["none", "input", "refuse", "crash", "degrade"] = Field("none", description="Fail on purpose (tests).")
    filter: Filter = Field(default_factory=Filter, description="Filter settings.")


CONFIG = EchoConfig
