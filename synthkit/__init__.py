"""synthkit: example-based 3D model and texture synthesis from five graphics papers."""

__version__ = "0.1.0"
