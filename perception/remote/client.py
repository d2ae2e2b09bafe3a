"""A model served elsewhere (``gva serve``, or any server of the protocol) as a PerceptionModel.

``--model ws://HOST:PORT``: each ``predict_frame`` sends the frame and condition
(:mod:`perception.remote.messages`) and reads the targets back. Whatever goes wrong on the wire
(the server is down, slower than ``timeout_s``, answers garbage or a text frame) raises
:class:`RemoteModelError` with why: a trial records it as ``perception_failed`` and the run goes
on. The next prediction reconnects; a server that then announces another model than the one
the run started with is refused, so every trial of a run was answered by the model its
``run.json`` names. The API key comes from the environment (:data:`API_KEY_VARIABLE`), never a
command line or a record.
"""

from __future__ import annotations

import functools
import os
import weakref
from collections.abc import Mapping
from typing import Any
from urllib.parse import urlsplit

from websockets.exceptions import InvalidStatus, WebSocketException
from websockets.sync.client import ClientConnection, connect

from perception.errors import InvalidInputError, NoAnswerError, PerceptionError
from perception.interface import (
    NO_CONDITION,
    Condition,
    LabelKind,
    ModelInput,
    PerceptionModel,
    Prediction,
    RgbdFrame,
)
from perception.learning.learnable import ModelSpec
from perception.remote.codec import pack, unpack
from perception.remote.messages import (
    PROTOCOL,
    read_announced,
    read_prediction,
    request_message,
)
from perception.remote.server import MAX_MESSAGE_BYTES

API_KEY_VARIABLE = "GVA_API_KEY"
"""The environment variable a client reads its API key from (sent as ``Api-Key <key>``)."""
TIMEOUT_S = 30.0
"""How long a connection or a prediction may take before it costs its trial."""


class RemoteModelError(PerceptionError):
    """The server did not give a prediction: down, slow, refused, or an answer not one."""


class ServerSilentError(RemoteModelError, NoAnswerError):
    """The server gave no answer: unreachable, silent past the limit, or its connection closed."""


class ServerSaidError(RemoteModelError):
    """The server answered with a text frame (its error); the connection stays usable."""


def is_remote(model: str) -> bool:
    """Whether ``model`` names a served model (``ws://`` or ``wss://``)."""
    return isinstance(model, str) and model.startswith(("ws://", "wss://"))


def check_url(url: str) -> str:
    """``url`` if it is a websocket address with a host and a port in 1-65535, else one line.

    Raises:
        InvalidInputError: Names the model field, the address and what an address is.

    """
    allowed = "ws://HOST:PORT or wss://HOST:PORT, the port in 1-65535"
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError:
        raise InvalidInputError("model", url, allowed) from None
    if parts.scheme not in ("ws", "wss") or not parts.hostname or port is None or port < 1:
        raise InvalidInputError("model", url, allowed)
    return url


def _open(url: str, timeout_s: float) -> tuple[ClientConnection, dict[str, Any]]:
    """A connection to ``url`` and the metadata it announced on connect."""
    key = os.environ.get(API_KEY_VARIABLE)
    headers = {"Authorization": f"Api-Key {key}"} if key else None
    try:
        connection = connect(url, compression=None, max_size=MAX_MESSAGE_BYTES,
                             additional_headers=headers, open_timeout=timeout_s,
                             legacy=True)  # held across predictions, not a with-block
    except InvalidStatus as error:
        status = error.response.status_code
        hint = (f" (its API key: set {API_KEY_VARIABLE} to it" + (", now set but not it)"
                                                                  if key else ")")
                if status == 401 else "")
        raise RemoteModelError(f"server {url} refused the connection: HTTP {status}{hint}") \
            from error
    except (OSError, TimeoutError, WebSocketException) as error:
        raise ServerSilentError(f"server {url} unreachable: {type(error).__name__}: "
                               f"{error}") from error
    try:
        announced = unpack(_receive(connection, url, timeout_s))
    except (PerceptionError, InvalidInputError):
        connection.close()
        raise
    if not isinstance(announced, dict) or announced.get("protocol") != PROTOCOL:
        connection.close()
        raise RemoteModelError(f"server {url} announced no {PROTOCOL} model: "
                               f"{str(announced)[:200]}")
    try:
        read_announced(announced)
    except InvalidInputError as error:
        connection.close()
        raise RemoteModelError(f"server {url} announced metadata gva cannot record: "
                               f"{error}") from None
    return connection, announced


def _receive(connection: ClientConnection, url: str, timeout_s: float) -> bytes:
    try:
        data = connection.recv(timeout=timeout_s)
    except TimeoutError as error:
        raise ServerSilentError(f"server {url} gave no answer within {timeout_s:g} s") \
            from error
    except WebSocketException as error:
        raise ServerSilentError(f"server {url} closed the connection: {error}") from error
    if isinstance(data, str):  # openpi's protocol: a text frame is the server's error
        raise ServerSaidError(f"server {url}: {data.strip()[:500]}")
    return data


@functools.cache
def announced_metadata(url: str, timeout_s: float = TIMEOUT_S) -> Mapping[str, Any]:
    """What the server at ``url`` announces, asked once per process (the run's identity).

    Raises:
        InvalidInputError: It cannot be reached or serves no gva-pick model: one line, before
            any trial (``gva trials`` exits 2).

    """
    check_url(url)
    try:
        connection, announced = _open(url, timeout_s)
    except PerceptionError as error:
        raise InvalidInputError("model", url, f"a reachable gva serve server ({error})") \
            from error
    connection.close()
    return announced


def announced_spec(announced: Mapping[str, Any], url: str) -> ModelSpec | None:
    """The :class:`ModelSpec` a server announced (``spec``); None where it announced none.

    Raises:
        InvalidInputError: A ``spec`` that is not :meth:`ModelSpec.to_json`'s; one line.

    """
    data = announced.get("spec")
    if data is None:
        return None
    try:
        return ModelSpec.from_json(dict(data))
    except (KeyError, TypeError, ValueError) as error:
        raise InvalidInputError("model", url, "a server announcing a spec as a checkpoint's "
                                f"config.json holds it ({type(error).__name__}: {error})") \
            from error


class RemoteModel(PerceptionModel):
    """The model a server announces, predicting over its websocket (see the module docstring)."""

    name = "remote"

    def __init__(self, url: str, timeout_s: float = TIMEOUT_S,
                 announced: Mapping[str, Any] | None = None) -> None:
        """The model at ``url``; ``announced``: what it announced when the run began, if known.

        Given, nothing is asked until the first prediction, which refuses a server that now
        announces otherwise.
        """
        self.url, self.timeout_s = url, timeout_s
        self.announced = dict(announced_metadata(url, timeout_s) if announced is None
                              else announced)
        try:
            self.label_kind = LabelKind(self.announced.get("label_kind"))
            self.inputs = frozenset(ModelInput(i) for i in self.announced.get("inputs", ()))
        except (ValueError, TypeError) as error:
            raise InvalidInputError("model", url, "a server announcing label_kind and inputs "
                                    f"gva knows ({error})") from error
        self.attention_per_target = bool(  # type: ignore[misc]  # the served class's, not ours
            self.announced.get("attention_per_target", True))
        self.spec: ModelSpec | None = announced_spec(self.announced, url)
        """What the served model was trained for (a checkpoint's spec), None where not announced;
        ``gva trials`` checks it against the task as it checks a checkpoint in-process."""
        self._connection: ClientConnection | None = None

    def __repr__(self) -> str:
        return f"RemoteModel({self.url!r}, {self.announced.get('name')!r})"

    def _connected(self) -> ClientConnection:
        if self._connection is None:
            connection, announced = _open(self.url, self.timeout_s)
            if announced != self.announced:
                connection.close()
                raise RemoteModelError(f"server {self.url} now announces another model "
                                       f"({announced.get('name')!r}, {announced}) than the run "
                                       f"started with: refused")
            self._connection = connection
            weakref.finalize(self, connection.close)  # a clean close, also at exit
        return self._connection

    def predict_frame(self, frame: RgbdFrame, condition: Condition = NO_CONDITION
                      ) -> Prediction:
        """The server's prediction for ``frame``; :class:`RemoteModelError` if none came."""
        data = pack(request_message(frame, condition))
        connection = self._connected()
        try:
            connection.send(data)
            reply = _receive(connection, self.url, self.timeout_s)
        except ServerSaidError:
            raise
        except RemoteModelError:
            self.close()  # a late or lost answer: the next prediction starts afresh
            raise
        except WebSocketException as error:
            self.close()
            raise ServerSilentError(f"server {self.url} closed the connection: {error}") \
                from error
        try:
            return read_prediction(unpack(reply))
        except InvalidInputError as error:
            raise RemoteModelError(f"server {self.url} answered no prediction: {error}") \
                from error

    def close(self) -> None:
        """Closes the connection (the next prediction opens another)."""
        if self._connection is not None:
            self._connection.close()
            self._connection = None
