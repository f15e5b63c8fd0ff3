"""The package's shape, checked on its source: the library never imports the command line, and
files are replaced atomically in one place only."""

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
