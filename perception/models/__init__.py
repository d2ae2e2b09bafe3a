"""Learnable perception models, one file each over the shared pieces in :mod:`.base`.

``kqv``: the paper's Key-Query-Value visual attention model (:class:`KqvModel`; its network
in :mod:`.kqv_net`, its settings in :mod:`.kqv_config`).
The paper's comparison models (Table II), over the shared pieces in :mod:`.baselines`:
``keypoint`` (FCN + spatial softmax, :class:`KeypointModel`), ``dsae`` (Deep Spatial AE,
:class:`DsaeModel`), ``conv_ae`` (Convolutional AE, :class:`ConvAeModel`) and ``fcn``
(vanilla FCN, :class:`FcnModel`).
"""
