"""Numerical stability at the extremes (issue #15): ``prtbench stability``.

Every registered method is run at the edges of its own knobs (generated from its ``Config``
fields: :mod:`.cases`), at its own edges (:mod:`.edges`: a 10⁶-triangle mesh, CPCA extremes,
probes inside geometry, |∇d| ≪ 1), under extreme lights (:mod:`.lights`) and on transformed
scenes (:mod:`.scenes`) — the built-in base scenes, or a user's file (``--scene PATH``, its
rows and report kept apart under the file's hashed name) — through the ordinary runner in
one process per case with a timeout (:mod:`.run`); each outcome is classified ok / degraded / refused / failed (:mod:`.outcome`),
stored (:mod:`.matrix`) and reported (:mod:`.report`).
"""
