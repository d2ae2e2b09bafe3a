"""Text conditions: a sentence's embedding, and which target its words name.

:mod:`~perception.language.sentences` embeds a sentence with a frozen, pinned all-MiniLM-L6-v2
(never downloaded); :mod:`~perception.language.sentence_reading` reads the target a sentence
names from its token embeddings (docs/decisions/open-conditions.md).
"""
