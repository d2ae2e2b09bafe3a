"""Learnable perception models, one file each over the shared pieces in :mod:`.base`.

``kqv``: the paper's Key-Query-Value visual attention model (:class:`KqvModel`).
"""
