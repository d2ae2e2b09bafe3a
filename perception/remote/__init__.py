"""Models that run elsewhere: ``gva serve`` and ``--model ws://HOST:PORT`` (docs/plugins.md).

:mod:`~perception.remote.codec` (openpi's msgpack bytes), :mod:`~perception.remote.messages`
(the fields), :mod:`~perception.remote.server` and :mod:`~perception.remote.client`.
"""
