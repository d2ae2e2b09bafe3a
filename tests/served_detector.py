"""The colour detector plug-in served in a thread: the model the served-model tests ask."""

from __future__ import annotations

import threading
from pathlib import Path

from perception.interface import PerceptionModel
from perception.remote.server import ModelServer, ServeSettings, metadata

PLUGINS = Path(__file__).resolve().parents[1] / "examples" / "plugins"
DETECTOR = "colour_detector:ColourDetector"


def serve(model: PerceptionModel, **settings: object) -> ModelServer:
    """``model`` (the detector) served on a free port in a daemon thread."""
    server = ModelServer(model, metadata(model, DETECTOR),
                         ServeSettings(DETECTOR, 0, **settings))  # type: ignore[arg-type]
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server
