"""Generators of the bundled samples in ``data-samples/`` (run by ``make samples``).

Each module ``synthkit.samples.<set>`` has ``generate(out_dir: Path) -> list[Path]`` that writes
its inputs and, beside each, ``<name>.truth.json`` with the known ground truth (lattice vectors,
periods, counts) that tests compare against. Generators are deterministic: the same bytes on
every run, checked against ``data-samples/SHA256SUMS``.
"""

SAMPLE_SETS = ("textures", "retarget", "petri", "textured", "reshape", "surfacing", "surfacing_transfer")
"""Module names under :mod:`synthkit.samples`, in generation order."""
