"""Shared file handling of datasets and checkpoints: errors, atomic writes, safetensors checks."""

from __future__ import annotations

import hashlib
import json
import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

from perception.errors import PerceptionError

MAX_SAFETENSORS_HEADER_BYTES = 100_000_000  # safetensors' own limit


class FileError(PerceptionError):
    """A file that cannot be used; the message names the kind, the file and what is wrong."""

    kind: ClassVar[str] = "file"

    def __init__(self, path: Path, problem: str) -> None:
        self.path, self.problem = path, problem
        super().__init__(f"{self.kind} {path}: {problem}")


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes, read a megabyte at a time."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def atomic_write(path: Path, write: Callable[[Path], Any]) -> None:
    """Runs ``write`` on a temporary file beside ``path``, syncs it, then renames it into place.

    A crash never leaves half a file under the final name.
    """
    temporary = path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}.tmp")
    try:
        write(temporary)
        with temporary.open("rb+") as file:
            os.fsync(file.fileno())
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def read_safetensors_header(path: Path, error: type[FileError]) -> dict[str, Any]:
    """The header JSON of a safetensors file, after checking that the file is whole.

    Raises ``error`` for a missing file, a file that is not safetensors, a damaged header, or a
    file shorter (truncated) or longer than its header says.
    """
    if not path.is_file():
        raise error(path, "not a file" if path.exists() else "no such file")
    size = path.stat().st_size
    with path.open("rb") as file:
        length = int.from_bytes(file.read(8), "little")
        if file.read(1) != b"{" or length > MAX_SAFETENSORS_HEADER_BYTES:
            raise error(path, "not a safetensors file: it does not start with an 8-byte header "
                        "length followed by a JSON header")
        if length > size - 8:
            raise error(path, f"truncated: {size} bytes, but the header alone needs "
                        f"{8 + length}")
        raw = b"{" + file.read(length - 1)
    try:
        header = json.loads(raw.decode("utf-8"))
        ends = [int(entry["data_offsets"][1]) for name, entry in header.items()
                if name != "__metadata__"]
    except (UnicodeDecodeError, ValueError, TypeError, KeyError, IndexError,
            AttributeError) as damaged:
        raise error(path, f"the header JSON is damaged ({damaged})") from damaged
    expected_size = 8 + length + max(ends, default=0)
    if size != expected_size:
        state = "truncated" if size < expected_size else "longer than its header says"
        raise error(path, f"{state}: {size} bytes, the header describes {expected_size}")
    return dict(header)
