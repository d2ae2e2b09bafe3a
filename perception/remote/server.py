"""``gva serve``: any gva model over a websocket, in openpi-client's policy-server protocol.

The protocol is ``openpi-client`` 0.1.2's ``WebsocketClientPolicy``: on connect the server
sends its metadata (:func:`metadata`, a msgpack map); each binary frame from the client is a
request (:mod:`perception.remote.messages`), answered by a binary frame, the prediction; an error
is a text frame, and the connection stays open for the next request. A bad API key (the
``Authorization: Api-Key <key>`` header that client sends) is refused at the handshake with 401,
a message over :data:`MAX_MESSAGE_BYTES` closes its connection (1009), a malformed one is
answered with a text frame; each is logged, and the server keeps serving others. Predictions run
one at a time (a torch model is not thread-safe). No simulator here: a server needs the model and
``perception`` only.
"""

from __future__ import annotations

import hashlib
import hmac
import http
import inspect
import logging
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response
from websockets.sync.server import Server, ServerConnection, serve

from perception.errors import InvalidInputError
from perception.interface import PerceptionModel
from perception.learning.learnable import ModelSpec
from perception.plugins import build_plugin, installed_models, is_class_path
from perception.remote.codec import pack, unpack
from perception.remote.messages import PROTOCOL, prediction_message, read_request

LOG = logging.getLogger("gva.serve")
MAX_MESSAGE_BYTES = 64 * 2**20
"""The largest request read: a 4K RGB-D frame is ~60 MB; anything larger is refused unread."""
DEFAULT_HOST = "127.0.0.1"  # loopback unless told otherwise: a model is no public service
REFUSED_MODELS = frozenset({"oracle", "oracle-view"})  # read the truth: no model to serve


@dataclass(frozen=True)
class ServeSettings:
    """What ``gva serve`` serves, where, and to whom (``api_key`` None: anyone who connects).

    ``max_message_bytes``: a longer request closes its connection unread (1009).
    """

    model: str
    port: int
    host: str = DEFAULT_HOST
    api_key: str | None = None
    model_class: str | None = None
    max_message_bytes: int = MAX_MESSAGE_BYTES

    def __post_init__(self) -> None:
        if not 0 <= self.port <= 65535:
            raise InvalidInputError("port", self.port, "an integer in 0-65535 (0: any free port)")
        if self.api_key is not None and not self.api_key.strip():
            raise InvalidInputError("api_key", "an empty key", "a non-empty key, or none")
        if self.max_message_bytes < 1024:
            raise InvalidInputError("max_message_bytes", self.max_message_bytes,
                                    "an integer >= 1024")


def load_served_model(model: str, model_class: str | None = None) -> PerceptionModel:
    """The model ``model`` names, loaded as ``gva trials --model`` takes it.

    A checkpoint folder, or a model without weights (``package.module:Class`` or an installed
    plug-in's name).

    Raises:
        InvalidInputError: ``oracle`` (it reads the truth), a remote model, or a model that
            cannot be found or built; one line.

    """
    if model in REFUSED_MODELS or model.startswith(("ws://", "wss://")):
        raise InvalidInputError("model", model, "a checkpoint folder, 'package.module:Class' or "
                                "an installed plug-in's name (not the oracle, which reads the "
                                "simulator's truth; not a remote model)")
    if Path(model).is_dir():
        from perception.registry import load_model  # torch: only for a checkpoint

        return load_model(model, model_class)
    if model_class is not None:
        raise InvalidInputError("model_class", model_class, "only with a checkpoint folder")
    if not (is_class_path(model) or model in installed_models()):
        raise InvalidInputError("model", model, "a checkpoint folder, 'package.module:Class' or "
                                "an installed plug-in's name")
    return build_plugin(model)


def metadata(model: PerceptionModel, source: str) -> dict[str, Any]:
    """What the server announces on connect: who the model is, what it reads and predicts.

    ``weights_sha256``/``config_sha256`` for a checkpoint (as its ``config.json`` holds them),
    ``source_sha256`` of the class's file for a model without weights: two servers of the same
    model announce the same identity, whatever their address. A learnable model also announces
    its ``spec`` (:meth:`~perception.learning.learnable.ModelSpec.to_json`: scene, task,
    condition, targets, image size, camera, sensor), which a client checks against its task as
    it checks a checkpoint in-process.
    """
    cls = type(model)
    data: dict[str, Any] = {
        "protocol": PROTOCOL, "name": model.name, "class": f"{cls.__module__}:{cls.__qualname__}",
        "label_kind": model.label_kind.value, "inputs": sorted(i.value for i in model.inputs),
        "attention_per_target": bool(cls.attention_per_target)}
    if Path(source).is_dir():
        from perception.learning.checkpoint import read_config

        config = read_config(source)
        data |= {"checkpoint": Path(source).resolve().name} | {
            key: config[key] for key in ("weights_sha256", "config_sha256") if key in config}
        spec = getattr(model, "spec", None)
        if isinstance(spec, ModelSpec):  # a learnable model's: what it was trained for
            data["spec"] = spec.to_json()
    else:
        try:
            data["source_sha256"] = hashlib.sha256(
                Path(inspect.getfile(cls)).read_bytes()).hexdigest()
        except (OSError, TypeError):
            pass  # a class without a file (built at run time): no source to hash
    return data


class ModelServer:
    """A model served on a websocket; :meth:`serve_forever` blocks, :meth:`shutdown` stops it."""

    def __init__(self, model: PerceptionModel, announced: Mapping[str, Any],
                 settings: ServeSettings) -> None:
        self.model, self.settings, self.announced = model, settings, dict(announced)
        self._metadata = pack(self.announced)
        self._lock = threading.Lock()
        self._server: Server = serve(self._handle, settings.host, settings.port,
                                     compression=None, max_size=settings.max_message_bytes,
                                     process_request=self._check_request)
        self.port: int = int(self._server.socket.getsockname()[1])
        """The port it listens on (the one the OS chose, for port 0)."""

    def serve_forever(self) -> None:
        """Serves until :meth:`shutdown`."""
        self._server.serve_forever()

    def shutdown(self) -> None:
        """Stops serving and closes the socket."""
        self._server.shutdown()

    def _check_request(self, connection: ServerConnection, request: Request) -> Response | None:
        """The handshake: ``/healthz`` answers OK (as openpi's server), a bad key 401."""
        if request.path == "/healthz":
            return connection.respond(http.HTTPStatus.OK, "OK\n")
        key = self.settings.api_key
        if key is None:
            return None
        given = request.headers.get("Authorization", "")
        if hmac.compare_digest(given.encode(), f"Api-Key {key}".encode()):
            return None
        LOG.warning("refused %s: %s API key", connection.remote_address,
                    "a wrong" if given else "no")
        return connection.respond(http.HTTPStatus.UNAUTHORIZED, "a valid API key is needed "
                                  "(header Authorization: Api-Key <key>)\n")

    def _handle(self, connection: ServerConnection) -> None:
        """One client: the metadata, then a reply per request until it closes."""
        peer = connection.remote_address
        LOG.info("connection from %s", peer)
        try:
            connection.send(self._metadata)
            for data in connection:
                connection.send(self._reply(data, peer))
        except ConnectionClosed as closed:
            codes = {frame.code for frame in (closed.rcvd, closed.sent) if frame is not None}
            if 1009 in codes:  # MESSAGE_TOO_BIG
                LOG.warning("refused %s: a message over %d bytes", peer,
                            self.settings.max_message_bytes)
        LOG.info("connection from %s closed", peer)

    def _reply(self, data: str | bytes, peer: Any) -> str | bytes:
        """The prediction's bytes, or a text frame that says why there is none."""
        if isinstance(data, str):
            LOG.warning("refused %s: a text frame", peer)
            return "error: requests are binary msgpack frames, not text"
        try:
            request = read_request(unpack(data))
        except InvalidInputError as error:
            LOG.warning("refused %s: %s", peer, error)
            return f"error: malformed request: {error}"
        try:
            with self._lock:
                prediction = self.model.predict_frame(request.frame, request.condition)
            return pack(prediction_message(prediction))
        except Exception as error:  # the model's failure is the client's answer, not a crash
            LOG.info("%s: %s raised %s: %s", peer, self.model.name, type(error).__name__, error)
            return f"error: {self.model.name}'s predict raised {type(error).__name__}: {error}"


def start_server(settings: ServeSettings) -> ModelServer:
    """The server of ``settings``: the model loaded and checked, the port bound, not yet serving."""
    model = load_served_model(settings.model, settings.model_class)
    return ModelServer(model, metadata(model, settings.model), settings)
