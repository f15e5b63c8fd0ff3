import pytest
from click.testing import CliRunner


@pytest.fixture
def runner():
    """A click test runner; ``result.stdout`` and ``result.stderr`` are kept apart."""
    return CliRunner()
