"""The claims ledger of the five sources (DESIGN.md §20): every checkable claim, one entry each.

Each module holds one source's claims as a tuple ``CLAIMS`` of
:class:`prtbench.bench.claims.Claim`: the quote, the paper's value, the report whose stored run
measures it, how ours is read from that run (:mod:`.measures`), the rule that decides
(:mod:`.rules`) and, for a contradiction, the measurement that explains it. ``prtbench claims``
finds this tuple by name (:func:`prtbench.bench.claims.all_claims`) and writes
``reports/claims.md`` and ``.csv``.
"""

from __future__ import annotations

from reproductions.claims import (
    belcour_2022,
    raghavan_2023,
    ramamoorthi_lecture,
    sirikonda_2022,
    sirikonda_2023,
)
from reproductions.claims.sources import SOURCES

CLAIMS = (*sirikonda_2022.CLAIMS, *sirikonda_2023.CLAIMS, *belcour_2022.CLAIMS,
          *raghavan_2023.CLAIMS, *ramamoorthi_lecture.CLAIMS)

__all__ = ["CLAIMS", "SOURCES"]
