"""The sentence encoder: pinned weights, offline, one vector per sentence, cached."""

from __future__ import annotations

import socket

import numpy as np
import pytest

import perception.language.sentences as sentences
from perception.errors import InvalidInputError
from perception.files import file_sha256
from perception.interface import Condition, ConditionKind
from perception.language.sentences import (
    EMBEDDING_SIZE,
    VOCABULARY_SIZE,
    WEIGHTS_SHA256,
    SentenceEncoder,
    model_folder,
)


def _no_network(*args, **kwargs):
    raise AssertionError("the sentence encoder tried the network")


@pytest.fixture(scope="module")
def encoder(tmp_path_factory) -> SentenceEncoder:
    """The packaged encoder, unpacked into a cache of this test's, with no network at all."""
    cache = tmp_path_factory.mktemp("cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("GVA_CACHE", str(cache))
        patch.setattr(socket.socket, "connect", _no_network)
        return SentenceEncoder()


def test_the_packaged_weights_are_the_pinned_revision(encoder, tmp_path, monkeypatch):
    monkeypatch.setenv("GVA_CACHE", str(tmp_path))  # unpacked again, here
    assert file_sha256(model_folder() / "model.safetensors") == WEIGHTS_SHA256
    assert (tmp_path / f"all-MiniLM-L6-v2-{WEIGHTS_SHA256[:12]}" / "tokenizer.json").is_file()


def test_a_changed_weights_file_is_refused_naming_both_hashes(tmp_path):
    (tmp_path / "model.safetensors").write_bytes(b"not the model")
    with pytest.raises(InvalidInputError, match=WEIGHTS_SHA256) as refused:
        SentenceEncoder(tmp_path)
    assert file_sha256(tmp_path / "model.safetensors") in str(refused.value)
    with pytest.raises(InvalidInputError, match=r"model\.safetensors"):
        SentenceEncoder(tmp_path / "missing")


def test_sentences_become_unit_vectors_near_for_the_same_meaning(encoder, monkeypatch):
    monkeypatch.setattr(socket.socket, "connect", _no_network)
    mug, cup, spray = (encoder.encode(s) for s in (
        "pick up the mug", "grab the cup", "the bottle you spray with"))
    assert mug.shape == (EMBEDDING_SIZE,) and mug.dtype == np.float32
    assert np.linalg.norm(mug) == pytest.approx(1.0, abs=1e-5)
    assert float(mug @ cup) > float(mug @ spray)
    assert encoder.encode("pick up the mug") is mug  # cached: the same array
    with pytest.raises(ValueError):
        mug[0] = 2.0  # read-only, as the cache shares it
    with pytest.raises(InvalidInputError, match="sentence"):
        encoder.encode("  ")


def test_token_embeddings_are_the_words_before_pooling(encoder, monkeypatch):
    monkeypatch.setattr(socket.socket, "connect", _no_network)
    tokens = encoder.tokens("the one on the right")
    assert tokens.shape == (7, EMBEDDING_SIZE)  # [CLS], five words, [SEP]
    assert tokens.dtype == np.float32 and encoder.tokens("the one on the right") is tokens
    pooled = tokens.mean(axis=0)  # the pooled embedding is their mean, made unit length
    np.testing.assert_allclose(pooled / np.linalg.norm(pooled),
                               encoder.encode("the one on the right"), atol=1e-5)
    with pytest.raises(InvalidInputError, match="sentence"):
        encoder.tokens("")


def test_token_ids_name_each_token_row(encoder, monkeypatch):
    """One word-piece id per row of the token embeddings, so a reader can tell words apart."""
    monkeypatch.setattr(socket.socket, "connect", _no_network)
    for sentence in ("the one on the right", "the right-side object please"):
        ids = encoder.ids(sentence)
        assert ids.shape == (encoder.tokens(sentence).shape[0],) and ids.dtype == np.int64
        assert ids.max() < VOCABULARY_SIZE and encoder.ids(sentence) is ids
    right = encoder.ids("the right-side object please")
    assert right[2] == encoder.ids("the one on the right")[5]  # "right" is one piece, both times
    with pytest.raises(InvalidInputError, match="sentence"):
        encoder.ids(" ")


def test_a_text_conditions_vector_is_its_sentences_embedding(encoder, monkeypatch):
    monkeypatch.setattr(socket.socket, "connect", _no_network)
    monkeypatch.setattr(sentences, "shared_encoder", lambda: encoder)
    condition = Condition(ConditionKind.TEXT, "the thing you spray with")
    vector = condition.vector()
    np.testing.assert_array_equal(vector, encoder.encode("the thing you spray with"))
    vector[0] = 2.0  # the caller's own copy: the cached embedding is untouched
    assert encoder.encode("the thing you spray with")[0] != 2.0
