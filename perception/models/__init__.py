"""Learnable perception models, one file each, over what :mod:`perception.learning` shares.

The torch pieces (:mod:`~perception.learning.torch_pieces`) and the rotation codes
(:mod:`~perception.learning.rotations`) live there, below every model: nothing in
``learning`` imports a model.

``kqv``: the paper's Key-Query-Value visual attention model (:class:`KqvModel`; its network
in :mod:`.kqv_net`, its settings in :mod:`.kqv_config`).
The paper's comparison models (Table II), over the shared pieces in :mod:`.baselines`:
``keypoint`` (FCN + spatial softmax, :class:`KeypointModel`), ``dsae`` (Deep Spatial AE,
:class:`DsaeModel`), ``conv_ae`` (Convolutional AE, :class:`ConvAeModel`) and ``fcn``
(vanilla FCN, :class:`FcnModel`).
"""
