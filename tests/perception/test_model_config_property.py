"""Generated model config files thrown at ``read_model_config`` (issue 63).

Whatever a file holds (every config field of each model with values from its range, its edges,
wrong types, NaN and inf, 64-bit and beyond, unknown keys, tables, arbitrary text and bytes),
reading it either gives settings the model's config accepts, or is refused by an
``InvalidInputError`` in one line naming the file. Any other exception fails the test.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from perception.interface import InvalidInputError
from perception.model_config_file import read_model_config
from perception.registry import trainable

MODELS = ("kqv", "kqv-paper", "keypoint-16", "dsae-16", "conv-ae", "fcn")
FILE_NAME = "fuzz-config.toml"
_EDGE_NUMBERS = [0, -1, 1, 2**63 - 1, 2**63, -(2**63) - 1, 10**30, 1e308, -1e308, 5e-324, 0.5,
                 4096, 4097, 1_000_000, 1_000_001, math.nan, math.inf, -math.inf]
_VALUES = st.one_of(
    st.sampled_from(_EDGE_NUMBERS), st.integers(-10, 5000), st.floats(-10, 2000),
    st.booleans(), st.text(max_size=10),
    st.lists(st.one_of(st.integers(-2, 2000), st.floats(-1, 10)), max_size=3),
    st.sampled_from(["cosine", "dot", "auto", "mlp", "fixed", "per-image", "paper", "ray"]))


def _fields(model: str) -> list[str]:
    cls, _ = trainable(model)
    return [f.name for f in dataclasses.fields(cls.config_class) if f.name != "seed"]


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return "{" + ", ".join(f"{json.dumps(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"


@st.composite
def config_files(draw: st.DrawFn) -> tuple[str, bytes]:
    """A model and a file: its config's fields set to anything, maybe a wrong key or table."""
    model = draw(st.sampled_from(MODELS))
    kind = draw(st.sampled_from(["keys"] * 6 + ["text", "bytes"]))
    if kind == "text":
        return model, draw(st.text(max_size=120)).encode()
    if kind == "bytes":
        return model, draw(st.binary(max_size=120))
    keys = draw(st.lists(st.sampled_from(_fields(model)), max_size=4, unique=True))
    lines = [f"{key} = {_toml_value(draw(_VALUES))}" for key in keys]
    extra = draw(st.sampled_from(["none"] * 4 + ["unknown", "seed", "table"]))
    if extra == "unknown":
        lines.append(f"{json.dumps(draw(st.text(min_size=1, max_size=8)))} = 1")
    elif extra == "seed":
        lines.append("seed = 3")
    elif extra == "table":
        lines.append("[section]\nkey = 1")
    return model, "\n".join(lines).encode()


@settings(max_examples=300, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(config_files())
def test_any_model_config_file_reads_or_is_refused_naming_the_file(tmp_path_factory,
                                                                   model_and_file):
    model, data = model_and_file
    path = Path(tmp_path_factory.mktemp("config")) / FILE_NAME
    path.write_bytes(data)
    try:
        settings_read = read_model_config(path, model)
    except InvalidInputError as error:
        message = str(error)
        assert "\n" not in message and FILE_NAME in message, message
        event(f"refused: {error.field.rpartition(': ')[2]}"[:60])
        return
    cls, preset = trainable(model)
    cls.config_class(**{**preset, **settings_read})  # what was read, the config accepts
    event("read")
