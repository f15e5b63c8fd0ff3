"""The package's shape, checked on its source (issue 27): the library never imports the command
line; files are replaced atomically in one place only; no import cycle (lazy imports included);
no function over 80 lines of code outside numba kernels; only pipelines, configs and the framework
raise ConfigError/InputError; no private name is imported from another module; stage modules import
neither files (``synthkit.io``) nor the layers above the methods; each method's options come from
``options_of`` with the config's defaults; barycentric coordinates and normals are defined once (issue 36)."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "synthkit"
MODULES = sorted(PACKAGE.rglob("*.py"))


def _imports(path: Path) -> list[str]:
    """Every module an import statement in ``path`` names, lazy imports inside functions included."""
    names = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
    return names


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_library_never_imports_the_command_line(path):
    assert not [m for m in _imports(path) if m == "synthkit.cli" or m.startswith("synthkit.cli.")]


def test_files_are_replaced_atomically_in_one_place():
    callers = []
    for path in MODULES:
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr in ("replace", "rename") and isinstance(node.func.value, ast.Name)
                    and node.func.value.id == "os"):
                callers.append(path.relative_to(PACKAGE).as_posix())
    # io/atomic.py replaces files; outdir.py renames whole output folders into place
    assert sorted(set(callers)) == ["io/atomic.py", "outdir.py"]


def _module_names() -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package."""
    names = {}
    for path in MODULES:
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
        names[".".join(parts)] = path
    return names


def _synthkit_imports(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The package's modules that ``name`` imports (relative, lazy and ``from x import module``)."""
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join([*base, *([node.module] if node.module else [])])
            for alias in node.names:
                found.add(f"{module}.{alias.name}" if f"{module}.{alias.name}" in known else module)
    return {m for m in found if m in known and m != name}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        item = stack.pop()
                        on_stack.discard(item)
                        component.append(item)
                        if item == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(sorted(graph[child]))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return found


def _registry_imports(known: dict[str, Path]) -> dict[str, set[str]]:
    """The imports the registries make by name: ``synthkit.methods`` loads each method's package
    (its spec), ``synthkit.methods.rooms`` its config and pipeline (:data:`synthkit.methods.METHODS`),
    ``synthkit`` each Python function's module (:data:`synthkit.API_FUNCTIONS`)."""
    import synthkit
    from synthkit.methods import METHODS

    rooms = {f"{package}{room}" for package in METHODS.values() for room in (".config", ".pipeline")}
    return {
        "synthkit.methods": set(METHODS.values()) & set(known),
        "synthkit.methods.rooms": rooms & set(known),
        "synthkit": set(synthkit.API_FUNCTIONS.values()) & set(known),
    }


def _import_graph() -> dict[str, set[str]]:
    known = _module_names()
    graph = {name: _synthkit_imports(name, path, known) for name, path in known.items()}
    for name, loaded in _registry_imports(known).items():
        graph[name] |= loaded
    return graph


def test_no_import_cycles():
    assert _cycles(_import_graph()) == []


def test_the_import_graph_follows_the_registries():
    graph = _import_graph()
    assert {"synthkit.methods.reshape.pipeline", "synthkit.methods.symtex.config"} <= graph["synthkit.methods.rooms"]
    assert "synthkit.methods.petri" in graph["synthkit.methods"]
    assert "synthkit.methods.surfacing.api" in graph["synthkit"]
    # the loop issue 36 found: runner -> (registry) pipeline -> api -> runner
    graph["synthkit.methods.reshape.pipeline"] |= {"synthkit.api"}
    graph["synthkit.api"] |= {"synthkit.runner"}
    assert any({"synthkit.runner", "synthkit.methods.rooms", "synthkit.api"} <= set(c) for c in _cycles(graph))


def test_the_cycle_finder_finds_a_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _cycles(graph) == [["a", "b", "c"]]


MAX_FUNCTION_LINES = 80
"""Most lines of code (no docstring, blank or comment lines) a function may have; numba kernels,
which cannot call helpers cheaply, are exempt."""


def _code_lines(node: ast.FunctionDef, lines: list[str]) -> int:
    first = node.body[0]
    docstring = set()
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        docstring = set(range(first.lineno, first.end_lineno + 1))
    return sum(1 for number in range(node.lineno, node.end_lineno + 1)
               if number not in docstring and lines[number - 1].strip()
               and not lines[number - 1].strip().startswith("#"))


def _is_kernel(node: ast.FunctionDef) -> bool:
    return any("jit" in ast.unparse(decorator) for decorator in node.decorator_list)


def test_functions_are_short():
    long = set()
    for path in MODULES:
        text = path.read_text()
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if (isinstance(node, ast.FunctionDef) and not _is_kernel(node)
                    and _code_lines(node, lines) > MAX_FUNCTION_LINES):
                long.add(f"{path.relative_to(PACKAGE).as_posix()}:{node.name}")
    assert sorted(long) == []


USER_ERRORS = ("ConfigError", "InputError")


def test_only_pipelines_and_configs_raise_user_errors():
    """A method's stage modules raise ValueError carrying the key; its pipeline maps it to a
    ConfigError or InputError (the framework outside ``methods/`` may raise them too)."""
    raising = set()
    for path in (PACKAGE / "methods").rglob("*.py"):
        if path.name in ("pipeline.py", "config.py", "api.py"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Raise) and node.exc is not None:
                raised = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
                if ast.unparse(raised) in USER_ERRORS:
                    raising.add(path.relative_to(PACKAGE).as_posix())
    assert sorted(raising) == []


def test_no_private_name_is_imported_from_another_module():
    imported = set()
    for path in MODULES:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("synthkit"):
                imported |= {f"{path.relative_to(PACKAGE).as_posix()}: {node.module}.{alias.name}"
                             for alias in node.names
                             if alias.name.startswith("_") and not alias.name.startswith("__")}
    assert sorted(imported) == []


ROOMS = ("config.py", "options.py", "pipeline.py", "outputs.py", "api.py")
"""The modules every method package has (synthkit/methods/__init__.py says what each holds)."""


@pytest.mark.parametrize("package", ["retarget", "surfacing", "reshape", "petri", "symtex"])
def test_every_method_has_the_same_rooms(package):
    folder = PACKAGE / "methods" / package
    assert [room for room in ROOMS if not (folder / room).is_file()] == []
    defined = {node.name for node in ast.parse((folder / "pipeline.py").read_text()).body
               if isinstance(node, ast.FunctionDef)}
    assert "compute" in defined and "run" not in defined  # the runner writes compute's result


FRAMEWORK_ROOMS = ("__init__.py", "config.py", "options.py", "pipeline.py", "outputs.py", "api.py")
"""The rooms of a method package that may reach files or the framework; every other module is a
stage (or a stage's helper) over arrays and models."""
ABOVE_THE_METHODS = ("synthkit.io", "synthkit.api", "synthkit.runner", "synthkit.batch", "synthkit.cluster")


def _reaches(path: Path, prefixes: tuple[str, ...]) -> list[str]:
    return sorted({m for m in _imports(path) for p in prefixes if m == p or m.startswith(p + ".")})


STAGE_MODULES = sorted(p for p in (PACKAGE / "methods").rglob("*.py") if p.name not in FRAMEWORK_ROOMS)


@pytest.mark.parametrize("path", STAGE_MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_stage_modules_import_neither_files_nor_the_layers_above(path):
    assert _reaches(path, ABOVE_THE_METHODS) == []


@pytest.mark.parametrize("path", sorted(p for p in (PACKAGE / "methods").rglob("*.py") if p.name != "api.py"),
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_method_imports_the_api_layer(path):
    """A method's pipeline and outputs build :class:`synthkit.result.Result`; only its ``api.py``
    (the Python function) uses :mod:`synthkit.api`."""
    assert _reaches(path, ("synthkit.api", "synthkit.runner")) == []


def _default_config(name: str):
    """Method ``name``'s config with every default, its required keys taken from its first bundled
    config (unvalidated beyond those: ``model_construct``)."""
    from synthkit.runner import load_method_config

    path = next(p for p in sorted((PACKAGE.parent / "configs").glob("*/*.yaml")) if p.parent.name == name)
    _, given, _ = load_method_config(path)
    required = {k: getattr(given, k) for k, f in type(given).model_fields.items() if f.is_required()}
    return type(given).model_construct(**required)


def _option_defaults(value, where: str):
    """``(where, field, default, value)`` of every field with a default in the dataclasses of ``value``."""
    import dataclasses

    if isinstance(value, tuple):
        return [row for k, item in enumerate(value) for row in _option_defaults(item, f"{where}[{k}]")]
    if not dataclasses.is_dataclass(value):
        return []
    rows = []
    for f in dataclasses.fields(value):
        field_value = getattr(value, f.name)
        if f.default is not dataclasses.MISSING:
            rows.append((where, f.name, f.default, field_value))
        rows += _option_defaults(field_value, f"{where}.{f.name}")
    return rows


@pytest.mark.parametrize("name", ["retarget", "petri-synth", "symmetry-texture", "surface-by-numbers", "reshape"])
def test_every_option_default_is_the_configs(name):
    """Each method builds its stages' options in one function, ``options_of(cfg)``; a default an
    options dataclass writes (most write none: the config's is the one) equals what ``options_of``
    makes of the config's defaults."""
    import importlib

    from synthkit.methods import METHODS

    module = importlib.import_module(f"{METHODS[name]}.options")
    builders = sorted(n for n, v in vars(module).items() if callable(v) and not isinstance(v, type)
                      and "options" in n and not n.startswith("_"))
    assert builders == ["options_of"]
    rows = _option_defaults(module.options_of(_default_config(name)), "options")
    assert [r for r in rows if r[2] != r[3]] == []


SHARED_GEOMETRY = ("vertex_normals", "child_uvs", "consistent_winding")


def test_barycentric_coordinates_and_normals_are_defined_once():
    """Barycentric coordinates, vertex normals, child UVs and consistent winding have one definition,
    in ``core/mesh.py`` (one rule for degenerate triangles)."""
    found = sorted(
        f"{path.relative_to(PACKAGE)}:{node.name}"
        for path in MODULES
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.FunctionDef) and (node.name.startswith("barycentric") or node.name in SHARED_GEOMETRY)
    )
    assert found == sorted(f"core/mesh.py:{name}" for name in ("barycentric", *SHARED_GEOMETRY))


def test_the_core_reads_its_tolerances_from_one_object():
    """No core module writes a tolerance of its own (a name ending in TOL or EPS bound to a number):
    they are :data:`synthkit.core.tol.tol`'s."""
    own = sorted(
        f"{path.name}:{target.id}"
        for path in sorted((PACKAGE / "core").glob("*.py"))
        for node in ast.parse(path.read_text()).body if isinstance(node, ast.Assign)
        for target in node.targets
        if isinstance(target, ast.Name) and target.id.rstrip("_").endswith(("TOL", "EPS"))
        and isinstance(node.value, ast.Constant)
    )
    assert own == []
