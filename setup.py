"""Package layout only (metadata lives in pyproject.toml): ``cli/`` is installed as ``synthkit.cli``."""

from setuptools import find_packages, setup

setup(
    packages=[*find_packages(include=["synthkit", "synthkit.*"]), "synthkit.cli"],
    package_dir={"synthkit.cli": "cli"},
)
