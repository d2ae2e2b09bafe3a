"""Experiments: the paper's tables, the job pool that runs them and the ``gva`` command line.

:mod:`.cli` lists the commands and :mod:`.commands` holds each one's options; :mod:`.table2`
and :mod:`.table3` are the paper's Tables II and III, built on what both use (:mod:`.tables`)
and run on the local process pool of :mod:`.jobs`.
"""
