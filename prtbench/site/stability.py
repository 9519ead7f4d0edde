"""The site's stability pages: ``prtbench stability``'s matrix, one page per profile.

The rows are :func:`prtbench.stability.matrix.stored_rows` (the newest stored row of each
(method, case), interrupted runs included and marked †, rows imported from a CSV marked ‡),
the same rows ``prtbench stability --from-store --partial`` writes its report from. Each row's
outcome class is its cell's CSS class (``outcome-ok``, ``outcome-degraded``,
``outcome-refused``, ``outcome-failed``), which ``site.css`` colours.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from prtbench.api.profiles import PROFILES
from prtbench.stability.matrix import stored_rows, stored_runs
from prtbench.stability.outcome import OUTCOMES
from prtbench.stability.report import IMPORTED_FROM, method_summary

#: Number columns of a method's table: (header, row key); the site prints 4 digits.
COLUMNS = (("PSNR_m (dB)", "psnr_masked"), ("FLIP_m", "flip_masked"),
           ("vs moderate PSNR (dB)", "psnr_vs_moderate"), ("artifact peak", "artifact_peak"),
           ("storage max", "storage_max"), ("over", "overflow"), ("under", "underflow"),
           ("precompute s", "precompute_s"), ("peak RSS MiB", "peak_rss_mib"),
           ("load", "load_1m"))
#: The SH core's rows (``sh-core``: projections of the case lights, no render).
CORE_COLUMNS = (("ringing", "ringing"), ("rel. L2", "rel_l2"))


@dataclass
class StabilityMethod:
    """One method's rows on a stability page, with its one-line summary."""

    method: str
    scene: str
    summary: str
    rows: list[dict]
    columns: tuple = COLUMNS


@dataclass
class StabilityPage:
    """``prtbench stability``'s stored matrix of one profile."""

    profile: str
    methods: list[StabilityMethod]
    outcomes: dict[str, int]
    degraded: list[dict] = field(default_factory=list)
    imported: int = 0
    partial: int = 0

    @property
    def file(self) -> str:
        """The page's file name in the site."""
        return f"stability-{self.profile}.html"

    @property
    def rows(self) -> list[dict]:
        """Every row of the page, method by method."""
        return [r for m in self.methods for r in m.rows]


def collect(results_path: Path) -> list[StabilityPage]:
    """A page for each profile whose stability rows the store holds (none: an empty list).

    Parameters
    ----------
    results_path : Path
        The results store (read only).

    Returns
    -------
    list of StabilityPage
    """

    pages = []
    for profile in PROFILES:
        if not stored_runs(profile=profile, results_path=results_path, partial=True)[0]:
            continue  # no stability run of this profile (an unreadable store raises)
        rows = stored_rows(profile=profile, results_path=results_path, partial=True)
        for r in rows:  # the page prints MiB, as the Markdown report does
            rss = r.get("peak_rss_bytes")
            r["peak_rss_mib"] = None if rss is None else float(rss) / 2**20
        methods = []
        for method in dict.fromkeys(r["method"] for r in rows):
            mine = [r for r in rows if r["method"] == method]
            core = mine[0].get("group") == "sh-core"
            methods.append(StabilityMethod(method=method, scene=str(mine[0].get("scene") or ""),
                                           summary=method_summary(method, mine), rows=mine,
                                           columns=CORE_COLUMNS if core else COLUMNS))
        counts = Counter(r["outcome"] for r in rows)
        pages.append(StabilityPage(
            profile=profile, methods=methods, outcomes={o: counts.get(o, 0) for o in OUTCOMES},
            degraded=[r for r in rows if r["outcome"] == "degraded"],
            imported=sum(bool(r.get(IMPORTED_FROM)) for r in rows),
            partial=sum(bool(r.get("partial_run")) for r in rows)))
    return pages


def measured(page: StabilityPage) -> list[dict[str, str]]:
    """The (profile, git_sha, renderer, device) of the page's rows, for the provenance footer."""
    keys = ("profile", "git_sha", "renderer", "device")
    return [dict(zip(keys, values)) for values in
            dict.fromkeys(tuple(str(r.get(k) or "") for k in keys) for r in page.rows)]
