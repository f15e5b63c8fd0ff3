"""A tiny method used only by the framework tests: copies or inverts an image."""

from synthkit.methods.spec import MethodSpec

SPEC = MethodSpec(functions=())
