"""Reshape a textured architectural mesh keeping edge directions and short edges (Cabral et al.).

Structure-preserving reshape of textured architectural scenes (Cabral, Lefebvre, Dachsbacher,
Drettakis, Eurographics 2009): the geometry (sections 3 and 5: a constraint graph of the textured
surfaces, strict and soft linear constraints solved by least squares with a factorization cached
per handle set, handles dragged in steps with a collapse check, chains of pieces joined at their
portals) and the textures (section 4: each stretched surface's texture reshaped, or with
``texture: continue`` its material continued at its texel scale). Beyond the paper: a resize in one
line (``scale`` / ``size``: handles at the model's ends, doors and windows keep their size) and
every part carried by a surface. From Python: :func:`synthkit.reshape` (:mod:`.api`).

Modules: ``config`` (schema), ``options`` (keys to arguments), ``pipeline`` (stages, errors),
``outputs`` (result and files), ``memory`` (meshes given in memory); stages ``graph``,
``constraints``, ``handles``, ``parts``, ``resize``, ``portals``, ``solver``, ``baseline``,
``retexture`` and ``texture/``; drawing in ``previews``.
"""

from synthkit.methods.spec import MethodSpec

SPEC = MethodSpec(
    functions=("reshape",),
    summary_keys=("before_after", "comparison"),
    main_keys=("mesh_",),
    set_example="solver.steps=20",
    init_values={"scale": {"x": 1.3}},
    init_required=("input",),
)
