"""``gva serve``: a model over a websocket (:mod:`perception.remote.server`).

For ``gva trials --model ws://HOST:PORT`` and any client of openpi-client's protocol.

Serves until interrupted (Ctrl-C: exit 0). The API key is ``--api-key`` or the environment's
``GVA_API_KEY``; without one any client that reaches the address is served, which is why the
server binds 127.0.0.1 unless ``--host`` says otherwise.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys

from experiments.commands.arguments import integer
from perception.errors import InvalidInputError
from perception.remote.client import API_KEY_VARIABLE
from perception.remote.server import DEFAULT_HOST, ServeSettings, start_server


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``gva serve``."""
    parser.add_argument("model", help="a checkpoint folder, package.module:Class, or a name an "
                        "installed package registers in gva.models (not oracle)")
    parser.add_argument("--port", type=integer(0), required=True,
                        help="the port to listen on (0: any free one, printed)")
    parser.add_argument("--host", default=DEFAULT_HOST,
                        help="the address to bind (%(default)s: this machine only)")
    parser.add_argument("--api-key", metavar="KEY",
                        help=f"clients must send it (Authorization: Api-Key KEY); default: "
                        f"${API_KEY_VARIABLE}, else none")
    parser.add_argument("--model-class", metavar="MODULE:CLASS",
                        help="the class that loads a checkpoint of an unregistered model")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Loads the model, prints its address and metadata, and serves until Ctrl-C."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s",
                        stream=sys.stderr)
    key = args.api_key  # '' is refused, not read as "no key": a key was meant
    if key is None:
        key = os.environ.get(API_KEY_VARIABLE)
        if key is not None and not key.strip():
            raise InvalidInputError(API_KEY_VARIABLE, key, "a non-empty key, or the variable "
                                    "unset to serve anyone who connects")
    settings = ServeSettings(args.model, args.port, args.host, key, args.model_class)
    server = start_server(settings)
    if "torch" in sys.modules:  # one thread, as gva trials predicts in-process: the same sums
        import torch

        torch.set_num_threads(1)
    print(f"serving {server.model.name} on ws://{settings.host}:{server.port}", flush=True)
    print(json.dumps(server.announced, sort_keys=True), flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.shutdown()
    return 0
