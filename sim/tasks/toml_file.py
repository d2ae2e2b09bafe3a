"""Reading a small user TOML file (a palette, a variant) safely, every mistake in one line."""

from __future__ import annotations

import hashlib
import tomllib
from pathlib import Path
from typing import Any, NamedTuple

from sim.errors import InvalidInputError


class TomlFile(NamedTuple):
    """A TOML file as read: its tables, and its bytes' SHA-256 (records name a file by it)."""

    tables: dict[str, Any]
    sha256: str


def read_toml_file(path: Path, where: str, max_bytes: int, kind: str) -> TomlFile:
    """The TOML file at ``path``, read no further than ``max_bytes``.

    ``where`` names the file in errors (``"palette mine.toml"``), ``kind`` what it is
    (``"a palette"``). A file that cannot be read, is too big, is not UTF-8 or not TOML is an
    :class:`InvalidInputError` naming it.
    """
    try:
        with path.open("rb") as file:
            data = file.read(max_bytes + 1)
    except OSError as error:
        raise InvalidInputError(where, str(path), f"a readable file ({error.strerror})") from None
    if len(data) > max_bytes:
        raise InvalidInputError(where, f"{len(data)} bytes or more",
                                f"{kind} of at most {max_bytes} bytes")
    try:
        return TomlFile(tomllib.loads(data.decode("utf-8-sig")), hashlib.sha256(data).hexdigest())
    except (UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError) as error:
        raise InvalidInputError(where, "not a TOML text in UTF-8", f"TOML ({error})") from None
