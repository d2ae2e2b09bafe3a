"""examples/07_export_lerobot.py runs as the docs say, and its round trip gives the same file."""

from __future__ import annotations

import runpy
from pathlib import Path

EXAMPLE = Path(__file__).parents[2] / "examples" / "07_export_lerobot.py"


def test_the_lerobot_example_round_trips(capsys, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # it writes runs/lerobot-example/ under the working folder
    runpy.run_path(str(EXAMPLE), run_name="__main__")
    assert "the same file as collected: True" in capsys.readouterr().out
