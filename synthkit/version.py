"""The package's version, apart from ``synthkit/__init__`` so that modules below the registries can
name it without importing the package's Python functions."""

__version__ = "0.1.0"
