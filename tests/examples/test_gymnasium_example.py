"""examples/06_gymnasium.py runs as the docs say, and its episodes pick."""

from __future__ import annotations

import runpy
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).parents[2] / "examples" / "06_gymnasium.py"


@pytest.mark.slow
def test_the_gymnasium_example_runs(capsys) -> None:
    runpy.run_path(str(EXAMPLE), run_name="__main__")
    printed = capsys.readouterr().out
    assert printed.count("reward 1 of 1, success") == 5, printed
