"""``gva collect --out``: a file or folder already there is refused before any collecting."""

from __future__ import annotations

import pytest
from gva_cli import gva
from user_models import synthetic_dataset


@pytest.fixture
def collected(monkeypatch: pytest.MonkeyPatch) -> list[object]:
    """The collections ``gva collect`` started (none should: each is a synthetic dataset)."""
    import experiments.commands.collect

    started: list[object] = []

    def collect(settings, out_path, progress=True):
        started.append(settings)
        return synthetic_dataset(size=2)

    monkeypatch.setattr(experiments.commands.collect, "collect", collect)
    return started


@pytest.mark.parametrize("kind", ["file", "folder"])
def test_an_existing_out_is_refused_before_collecting_in_one_line(tmp_path, collected, kind):
    # issue 63: a second collect into a.gva replaced the first dataset and exited 0; a folder
    # was refused only after collecting, with a raw "[Errno 21] Is a directory"
    out = tmp_path / "a.gva"
    if kind == "file":
        out.write_bytes(b"the first dataset")
    else:
        (out / "inside").mkdir(parents=True)
    status, stdout, stderr = gva("collect", "--scene", "yumi", "--task", "single", "--size", 2,
                                 "--seed", 5, "--out", out, "--no-progress")
    assert status == 2 and stdout == ""
    held = "" if kind == "file" else "; it is a folder"
    assert stderr == (f"gva collect: error: --out = '{out}' is not allowed: a .gva path that "
                      f"does not exist yet{held}\n")  # gva import's words
    assert collected == []
    if kind == "file":
        assert out.read_bytes() == b"the first dataset"
    else:
        assert [p.name for p in out.iterdir()] == ["inside"]
