"""Numerical stability at the extremes (issue #15): ``prtbench stability``.

Every registered method is run at the edges of its own knobs (generated from its ``Config``
fields: :mod:`.cases`), under extreme lights (:mod:`.lights`) and on transformed scenes
(:mod:`.scenes`), through the ordinary runner in one process per case with a timeout
(:mod:`.run`); each outcome is classified ok / degraded / refused / failed (:mod:`.outcome`),
stored (:mod:`.matrix`) and reported (:mod:`.report`).
"""
