"""The bytes of a remote model's messages: msgpack with numpy arrays as openpi encodes them.

``openpi-client`` 0.1.2 (``openpi_client/msgpack_numpy.py``), the protocol robot-learning policy
servers speak, packs an array as the map ``{b"__ndarray__": True, b"data": <raw bytes>,
b"dtype": <dtype.str, e.g. "<f4">, b"shape": [..]}`` and a numpy scalar as ``{b"__npgeneric__":
True, b"data": <item>, b"dtype": ..}`` (keys are msgpack bin, strings are str). This module
writes and reads the same bytes without pickle: object, void and complex arrays are refused on
both sides, and an array whose data does not fill its shape is refused, so a hostile message
cannot build anything but plain numbers. Its own few lines, not openpi-client (which pins
numpy < 2).
"""

from __future__ import annotations

import math
from typing import Any

import msgpack
import numpy as np

from perception.errors import InvalidInputError

REFUSED_KINDS = frozenset("VOc")
"""dtype kinds never sent nor read: void, object (pickle's door) and complex, as openpi."""


def _pack_array(obj: Any) -> Any:
    """The ``default`` hook of msgpack: numpy arrays and scalars as openpi's maps."""
    if isinstance(obj, np.ndarray | np.generic) and obj.dtype.kind in REFUSED_KINDS:
        raise InvalidInputError("array dtype", str(obj.dtype), "numbers or bools "
                                "(object, void and complex arrays are never sent)")
    if isinstance(obj, np.ndarray):
        return {b"__ndarray__": True, b"data": np.ascontiguousarray(obj).tobytes(),
                b"dtype": obj.dtype.str, b"shape": obj.shape}
    if isinstance(obj, np.generic):
        return {b"__npgeneric__": True, b"data": obj.item(), b"dtype": obj.dtype.str}
    raise TypeError(f"cannot send {type(obj).__name__}")


def _dtype(value: Any) -> np.dtype[Any]:
    """The dtype a message names, refused unless plain numbers or bools."""
    try:
        dtype = np.dtype(value if isinstance(value, str) else "")
    except TypeError as error:
        raise InvalidInputError("array dtype", value, "a numpy dtype string such as '<f4'") \
            from error
    if dtype.kind in REFUSED_KINDS or dtype.hasobject or not isinstance(value, str):
        raise InvalidInputError("array dtype", value, "numbers or bools, e.g. '|u1', '<f4'")
    return dtype


def _unpack_array(obj: dict[Any, Any]) -> Any:
    """The ``object_hook`` of msgpack: openpi's array maps back to numpy, checked."""
    if b"__ndarray__" in obj:
        dtype, data, shape = _dtype(obj.get(b"dtype")), obj.get(b"data"), obj.get(b"shape")
        if not isinstance(shape, list | tuple) or not all(
                isinstance(n, int) and n >= 0 for n in shape):
            raise InvalidInputError("array shape", shape, "a list of integers >= 0")
        size = math.prod(shape) * dtype.itemsize
        if not isinstance(data, bytes) or len(data) != size:
            given = len(data) if isinstance(data, bytes) else data
            raise InvalidInputError("array data", f"{given} bytes",
                                    f"{size} bytes (shape {list(shape)} of {dtype.str})")
        return np.frombuffer(data, dtype=dtype).reshape(shape)
    if b"__npgeneric__" in obj:
        dtype = _dtype(obj.get(b"dtype"))
        return dtype.type(obj.get(b"data"))
    return obj


def pack(message: Any) -> bytes:
    """``message`` (maps, lists, str, numbers, None, numpy arrays) as openpi's msgpack bytes."""
    packed: bytes = msgpack.packb(message, default=_pack_array)
    return packed


def unpack(data: bytes) -> Any:
    """The message in ``data``, arrays as read-only numpy arrays.

    Raises:
        InvalidInputError: Not msgpack, or an array openpi's encoding cannot hold; one line.

    """
    if not isinstance(data, bytes):
        raise InvalidInputError("message", type(data).__name__, "a binary msgpack frame")
    try:
        return msgpack.unpackb(data, object_hook=_unpack_array, strict_map_key=False)
    except InvalidInputError:
        raise
    except Exception as error:  # msgpack's own errors: ExtraData, FormatError, ValueError, ...
        why = str(error).strip() or "not a msgpack value (msgpack said no more)"
        raise InvalidInputError("message", f"{len(data)} bytes", "msgpack (openpi-client's "
                                f"encoding); reading it raised {type(error).__name__}: "
                                f"{why}") from error
