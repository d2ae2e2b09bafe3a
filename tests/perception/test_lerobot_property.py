"""Exported LeRobot folders mutated at random and imported (issue 63).

Files dropped, truncated or with bytes flipped; data columns dropped, widened or retyped; each
also with meta/gva.json's file list rewritten to match, as a tool that re-signs what it edits
would, so the checks past the list are exercised too. The import gives back the dataset
exported, or refuses in one line naming the folder. Never another exception.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from test_lerobot_format import make

from perception.errors import PerceptionError
from perception.interface import InvalidInputError
from perception.learning.lerobot_format import export_lerobot, import_lerobot

DATA = "data/chunk-000/file-000.parquet"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    dataset = make(depth_and_joints=True)
    root = export_lerobot(dataset, tmp_path_factory.mktemp("lerobot") / "out").folder
    return dataset, root


def _resign(root: Path) -> None:
    """meta/gva.json's file list rewritten to the folder as it now is."""
    gva = json.loads((root / "meta/gva.json").read_text())
    gva["files_sha256"] = {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes())
                           .hexdigest() for p in sorted(root.rglob("*"))
                           if p.is_file() and p.relative_to(root).as_posix() != "meta/gva.json"}
    (root / "meta/gva.json").write_text(json.dumps(gva))


def _mutate_column(root: Path, how: str, column: str) -> None:
    table = pq.read_table(root / DATA)
    if column not in table.column_names:
        return
    index = table.column_names.index(column)
    if how == "drop":
        table = table.remove_column(index)
    elif how == "widen":
        values = table.column(column).to_pylist()
        wider = [[*v, 0.0] if isinstance(v, list) else [v, 0.0] for v in values]
        table = table.set_column(index, column, pa.array(wider))
    else:  # retype: the column as strings
        table = table.set_column(index, column, pa.array([str(v) for v in
                                                          table.column(column).to_pylist()]))
    pq.write_table(table, root / DATA)


@settings(max_examples=40, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(how=st.sampled_from(["drop-file", "truncate", "flip", "drop", "widen", "retype"]),
       name=st.sampled_from(["meta/info.json", "meta/stats.json", "meta/tasks.parquet",
                             "meta/episodes/chunk-000/file-000.parquet", DATA, "meta/gva.json"]),
       column=st.sampled_from(["action", "index", "episode_index", "observation.image",
                               "observation.state", "observation.depth"]),
       at=st.floats(0, 1), resign=st.booleans())
def test_a_mutated_folder_imports_as_exported_or_is_refused_in_one_line(
        exported, tmp_path_factory, how, name, column, at, resign):
    dataset, original = exported
    root = Path(tmp_path_factory.mktemp("mutated")) / "out"
    shutil.copytree(original, root)
    path = root / name
    if how == "drop-file":
        path.unlink()
    elif how == "truncate":
        data = path.read_bytes()
        path.write_bytes(data[:int(at * len(data))])
    elif how == "flip":
        data = bytearray(path.read_bytes())
        data[int(at * (len(data) - 1))] ^= 0xFF
        path.write_bytes(bytes(data))
    else:
        _mutate_column(root, how, column)
    if resign and (root / "meta/gva.json").exists():
        try:
            _resign(root)
        except (json.JSONDecodeError, UnicodeDecodeError):
            pass  # gva.json itself mangled: nothing to re-sign
    try:
        imported = import_lerobot(root)
    except (PerceptionError, InvalidInputError) as error:
        assert "\n" not in str(error), str(error)
        event(f"refused ({how})")
        return
    assert np.array_equal(imported.images, dataset.images)  # accepted: the same data
    assert np.array_equal(imported.labels, dataset.labels)
    event(f"imported ({how})")
