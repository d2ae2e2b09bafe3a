"""The one JSON form of a dataset's records: what its metadata and scenes read back as.

A dataset keeps its camera, extras and scene records in the form they read back from its file
(:mod:`perception.learning.dataset_file`), so a dataset in memory equals the one loaded; and
its identity hashes their one canonical text.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from perception.errors import InvalidInputError


def json_form(name: str, value: Any) -> dict[str, Any]:
    """A copy of the dict ``value`` as it reads back from JSON; an error unless JSON-able."""
    if not isinstance(value, Mapping):
        raise InvalidInputError(name, type(value).__name__, "a JSON-able dict")
    try:
        return dict(json.loads(canonical_json(value)))
    except (TypeError, ValueError) as error:
        raise InvalidInputError(name, str(error), "JSON-able values: dicts with str keys, lists, "
                                "str, int, finite float, bool, None") from error


def canonical_json(value: Any) -> str:
    """The one JSON text of ``value``: sorted keys, no spaces, no NaN."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False)
