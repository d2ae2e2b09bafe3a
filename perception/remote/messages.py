"""What a remote model is sent and answers, field by field (docs/plugins.md, "A model served").

A request is what the plug-in contract gives ``predict_frame``: the frame (RGB, depth, the
camera's calibration) and the condition; a reply is a :class:`~perception.interface.Prediction`.
Both are plain maps of str keys, numbers, strings and numpy arrays, so a client in any language
with msgpack builds them; :mod:`perception.remote.codec` turns them into bytes. Reading a
message checks every field and names the first that is wrong, in one line.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from perception.camera import PinholeCamera, RgbdFrame
from perception.checks import MAX_OBJECT_TYPE_CHARS
from perception.errors import InvalidInputError
from perception.interface import Condition, ConditionKind, Prediction, Target

PROTOCOL = "gva-pick/1"
"""The message format's name and version: a request and the server's metadata carry it."""


@dataclass(frozen=True)
class Request:
    """A prediction a client asks for: the frame and the condition."""

    frame: RgbdFrame
    condition: Condition


def request_message(frame: RgbdFrame, condition: Condition) -> dict[str, Any]:
    """The request for ``frame`` and ``condition``, as a map to pack."""
    camera = frame.camera
    message: dict[str, Any] = {
        "protocol": PROTOCOL,
        "rgb": np.ascontiguousarray(frame.rgb, dtype=np.uint8),
        "depth_m": np.ascontiguousarray(frame.depth_m, dtype=np.float32),
        "camera": camera.to_json() | {"K": camera.K.astype(np.float64),
                                      "T_world_camera": camera.T_world_camera.astype(np.float64)},
        "condition": {"kind": condition.kind.value, "value": condition.value,
                      "choices": list(condition.choices), "picture": condition.picture},
    }
    if frame.robot_mask is not None:
        message["robot_mask"] = np.ascontiguousarray(frame.robot_mask, dtype=np.bool_)
    return message


def _field(message: Any, name: str, where: str = "") -> Any:
    if not isinstance(message, Mapping):
        raise InvalidInputError(where or "message", type(message).__name__, "a map")
    if name not in message:
        raise InvalidInputError(f"{where}{'.' if where else ''}{name}", "missing",
                                "present (docs/plugins.md lists every field)")
    return message[name]


def _array(value: Any, name: str, dtype: type, shape: str) -> np.ndarray:
    if not isinstance(value, np.ndarray) or value.dtype != dtype:
        found = f"{getattr(value, 'dtype', type(value).__name__)} {np.shape(value)}"
        raise InvalidInputError(name, found, f"a {np.dtype(dtype).name} array of shape {shape}")
    return value


def read_request(message: Any) -> Request:
    """The frame and condition in a request; one line naming the first wrong field."""
    protocol = _field(message, "protocol")
    if protocol != PROTOCOL:
        raise InvalidInputError("protocol", protocol, repr(PROTOCOL))
    camera_data = _field(message, "camera")
    if not isinstance(camera_data, Mapping):
        raise InvalidInputError("camera", type(camera_data).__name__, "a map")
    try:
        camera = PinholeCamera.from_json({k: v for k, v in camera_data.items()
                                          if k not in ("K", "T_world_camera")})
    except InvalidInputError as error:  # named as the request's field
        raise InvalidInputError(f"camera.{error.field}", error.value, error.allowed) from None
    rgb = _array(_field(message, "rgb"), "rgb", np.uint8, "(H, W, 3)")
    depth = _array(_field(message, "depth_m"), "depth_m", np.float32, "(H, W)")
    mask = message.get("robot_mask")
    if mask is not None:
        mask = _array(mask, "robot_mask", np.bool_, "(H, W)")
    frame = RgbdFrame(rgb, depth, camera, mask)
    asked = _field(message, "condition")
    kind = _field(asked, "kind", "condition")
    allowed = [k.value for k in ConditionKind]
    if kind not in allowed:
        raise InvalidInputError("condition.kind", kind, f"one of {', '.join(allowed)}")
    choices = _field(asked, "choices", "condition")
    if not isinstance(choices, list | tuple) or not all(isinstance(c, str) for c in choices):
        raise InvalidInputError("condition.choices", choices, "a list of strings")
    picture = asked.get("picture")
    value = None if kind == ConditionKind.IMAGE.value else _field(asked, "value", "condition")
    condition = Condition(ConditionKind(kind), value, tuple(choices), picture)
    return Request(frame, condition)


def prediction_message(prediction: Prediction) -> dict[str, Any]:
    """The reply for ``prediction``, as a map to pack."""
    return {
        "targets": [{"position_m": np.asarray(t.position_m, dtype=np.float64),
                     "rotation": None if t.rotation is None else
                     np.asarray(t.rotation, dtype=np.float64),
                     "object_type": t.object_type, "opening_m": t.opening_m}
                    for t in prediction.targets],
        "attention_px": np.asarray(prediction.attention_px, dtype=np.float64),
        "heatmaps": None if prediction.heatmaps is None else
        np.asarray(prediction.heatmaps, dtype=np.float32),
    }


def _number_array(value: Any, name: str) -> np.ndarray | None:
    if value is None:
        return None
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "fiu":
        raise InvalidInputError(name, type(value).__name__, "a numeric array")
    return value.astype(np.float64)


MAX_NAME_CHARS = 100
"""The longest model name a server may announce: a run's folders and table rows carry it."""
MAX_ANNOUNCED_BYTES = 64 * 1024
"""The most a server's announced metadata may take as JSON: it is written into every run's
``run.json`` and summary (a few hundred bytes from ``gva serve``)."""


def read_announced(message: Any) -> dict[str, Any]:
    """A server's announced metadata, if it is strict JSON of at most MAX_ANNOUNCED_BYTES.

    Strict: no NaN or infinity (which never equals itself, so a reconnect could never find the
    same model again, and strict JSON readers refuse the records), string keys, JSON types only.

    Raises:
        InvalidInputError: Names what is wrong, never echoing the (unbounded) value.

    """
    if not isinstance(message, dict):
        raise InvalidInputError("announced", type(message).__name__, "a map")
    try:
        text = json.dumps(message, allow_nan=False, sort_keys=True)
    except (TypeError, ValueError) as error:
        raise InvalidInputError("announced", f"not strict JSON ({str(error)[:100]})",
                                "a map of JSON values: finite numbers, strings, lists, maps") \
            from None
    if len(text.encode()) > MAX_ANNOUNCED_BYTES:
        raise InvalidInputError("announced", f"{len(text.encode())} bytes as JSON",
                                f"at most {MAX_ANNOUNCED_BYTES} bytes")
    name = message.get("name")  # a run's folders and rows are named by it
    if not isinstance(name, str) or not 0 < len(name) <= MAX_NAME_CHARS or \
            name in (".", "..") or any(c in name for c in "/\\\0"):
        shown = f"{len(name)} characters" if isinstance(name, str) and \
            len(name) > MAX_NAME_CHARS else repr(name)
        raise InvalidInputError("announced.name", shown, f"1-{MAX_NAME_CHARS} characters, no "
                                "slash (a run's folders are named by it)")
    return message


def read_prediction(message: Any) -> Prediction:
    """The prediction in a reply; one line naming the first wrong field."""
    targets = _field(message, "targets")
    if not isinstance(targets, list | tuple):
        raise InvalidInputError("targets", type(targets).__name__, "a list of target maps")
    read = []
    for k, target in enumerate(targets):
        where = f"targets[{k}]"
        position = _number_array(_field(target, "position_m", where), f"{where}.position_m")
        if position is None:
            raise InvalidInputError(f"{where}.position_m", None, "a (3,) array")
        object_type = target.get("object_type")
        if object_type is not None and (not isinstance(object_type, str)
                                        or len(object_type) > MAX_OBJECT_TYPE_CHARS):
            shown = f"{len(object_type)} characters" if isinstance(object_type, str) \
                else type(object_type).__name__  # never the value: it goes into records
            raise InvalidInputError(f"{where}.object_type", shown, "a string of at most "
                                    f"{MAX_OBJECT_TYPE_CHARS} characters, or None")
        opening = target.get("opening_m")
        if opening is not None and (not isinstance(opening, int | float)
                                    or not math.isfinite(opening)):
            raise InvalidInputError(f"{where}.opening_m", opening, "a finite number or None")
        read.append(Target(position, _number_array(target.get("rotation"), f"{where}.rotation"),
                           object_type, None if opening is None else float(opening)))
    attention = _number_array(message.get("attention_px"), "attention_px")
    return Prediction(tuple(read), np.zeros((0, 2)) if attention is None else attention,
                      _number_array(message.get("heatmaps"), "heatmaps"))
