"""The README's Python examples run as written (issue 26), and every public function is exported
with a numpydoc docstring (each method's test_<method>_api.py runs its docstring example)."""

import re
from pathlib import Path

import pytest

import synthkit

README = Path(__file__).resolve().parent.parent / "README.md"


def _python_blocks() -> list[str]:
    """The ```python blocks of the README's "From Python" section."""
    text = README.read_text()
    section = text.split("## From Python", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, flags=re.S)


def test_the_readme_shows_every_function():
    code = "\n".join(_python_blocks())
    for name in synthkit.API_FUNCTIONS:
        assert f"synthkit.{name}(" in code, name


@pytest.mark.slow
def test_the_readme_examples_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for block in _python_blocks():
        exec(compile(block, str(README), "exec"), {})


@pytest.mark.parametrize("name", sorted(synthkit.API_FUNCTIONS))
def test_each_function_is_exported_and_documented(name):
    function = getattr(synthkit, name)
    assert callable(function) and function.__name__ == name
    for part in ("Parameters", "Returns", "Raises", "Examples"):
        assert f"\n    {part}\n    ----" in function.__doc__, f"{name}: no {part} section"
