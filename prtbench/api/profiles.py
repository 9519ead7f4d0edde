"""Run profiles: how big a run is (DESIGN.md §10).

``smoke`` is for tests (seconds), ``quick`` is the default for make targets (minutes on 2 CPU
cores), ``paper`` uses the papers' parameters. The profile is printed and stored with every
result row; methods may declare per-profile config overrides (``Method.profile_overrides``).
"""

from __future__ import annotations

from dataclasses import dataclass

from prtbench.api.errors import UnknownNameError


@dataclass(frozen=True)
class Profile:
    """Run-size settings shared by every method.

    Attributes
    ----------
    name : str
    width, height : int
        Render and reference resolution.
    views : int
        Trajectory views rendered (evenly spread over the scene's trajectory).
    reference_spp : int
        Samples per pixel of the Mitsuba reference.
    timing_frames, timing_warmup : int
        GPU timer-query frames (median/p95 reported) and warm-up frames.
    """

    name: str
    width: int
    height: int
    views: int
    reference_spp: int
    timing_frames: int
    timing_warmup: int


PROFILES = {
    "smoke": Profile("smoke", 64, 48, 1, 32, 3, 1),
    "quick": Profile("quick", 320, 240, 4, 256, 10, 3),
    "paper": Profile("paper", 1920, 1080, 30, 1024, 100, 10),
}


def get_profile(name: str) -> Profile:
    """The named profile; unknown names list the accepted ones."""
    if name not in PROFILES:
        raise UnknownNameError("profile", name, PROFILES)
    return PROFILES[name]
