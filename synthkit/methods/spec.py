"""What the framework knows of a method, declared once in its package's ``__init__`` as ``SPEC``.

The command line (subcommand, flags, ``--set`` example, ``synthkit init``), the Python functions
(:data:`synthkit.API_FUNCTIONS`), the run summary, batch rows and the review page
(:mod:`synthkit.summary`) are all built from it. The rest of the contract is the package's rooms
(:mod:`synthkit.methods`): ``config.CONFIG``, ``pipeline.compute``, the ``Result`` subclasses in
``outputs`` and the functions in ``api``. Imports nothing heavy: the command line reads specs
before numpy loads.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["MethodSpec", "DEFAULT_SET_EXAMPLE"]

DEFAULT_SET_EXAMPLE = "seed=7"
"""The ``--set`` example of a method that names none."""


@dataclass(frozen=True)
class MethodSpec:
    """One method's declaration.

    Attributes
    ----------
    functions : the Python functions its ``api`` module defines (``synthkit.<function>``)
    headline : metrics shown in the one-line run summary, batch rows and the review page, in this
        order, when a run reports them (none reported: the first four scalar metrics)
    summary_keys : output keys of the image that shows a run's result best, most telling first
        (none present: the first PNG)
    main_keys : output keys of a run's main result, first present wins; a key ending in ``_`` is a
        prefix (reshape's ``mesh_<piece>``)
    cli_flags : extra boolean options of the subcommand: flag -> (``--set`` override, help)
    set_example : a real key of the method, shown in ``--set``'s help
    init_values : example values ``synthkit init`` writes for keys a config must give (dotted key
        -> value)
    init_required : optional keys ``synthkit init`` marks REQUIRED
    """

    functions: tuple[str, ...]
    headline: tuple[str, ...] = ()
    summary_keys: tuple[str, ...] = ()
    main_keys: tuple[str, ...] = ()
    cli_flags: dict[str, tuple[str, str]] = field(default_factory=dict)
    set_example: str = DEFAULT_SET_EXAMPLE
    init_values: dict[str, Any] = field(default_factory=dict)
    init_required: tuple[str, ...] = ()
