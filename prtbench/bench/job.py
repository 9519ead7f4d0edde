"""The one job type every driver submits, and where a job's files go.

A :class:`Job` is one measurement: a method's configuration rendered on a scene (with its
parameters and material variant) under a light, from the trajectory's views, at a resolution
and profile, and compared with a reference. ``prtbench run``, the paper tables and figures,
``sweep``, ``advise``, ``stability``, ``regress`` and the site's measurements all build Jobs
and hand them to :func:`prtbench.bench.submit.submit`, which validates every job before any
work, runs them on an executor (:mod:`prtbench.bench.executors`) and alone writes the results
store. ``label`` carries the driver's own keys (a table's row and column, a sweep's grid
values); it is not part of what is measured.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Job:
    """One configuration to measure.

    Attributes
    ----------
    method : str
        A registered method (``prtbench list methods``).
    scene : str
        A registered scene or an asset file's path.
    label : mapping
        The driver's keys for this job (e.g. ``{"ground": "2"}``), stored with report runs.
    variant : str
        Material variant, ``diffuse`` or ``glossy``.
    light : str, path or EnvironmentLight, optional
        A light name, an HDR file, or a light object (the stability matrix's extreme lights);
        None: the scene's default light.
    overrides : mapping
        Config knobs (``--set``), strict.
    scene_params : mapping
        Scene builder parameters (``--scene-param``).
    reference : str
        ``path`` (Mitsuba) or ``method:<name>``.
    reference_bounces : int, optional
        Interreflection bounces of the path reference (max depth = bounces + 2). One panel has
        one reference (docs/PROTOCOL.md), so a sweep comparing methods fixes it for all of
        them; None: the method's own ``bounces`` knob (0 where it has none).
    views : int, optional
        Trajectory views (None: the profile's count, capped by the scene's).
    resolution : (int, int), optional
        Width and height (None: the profile's).
    profile : str, optional
        ``smoke``, ``quick`` or ``paper``; None takes the profile the job is submitted in.
    """

    method: str
    scene: str
    label: Mapping[str, Any] = field(default_factory=dict)
    variant: str = "diffuse"
    light: Any = None
    overrides: Mapping[str, Any] = field(default_factory=dict)
    scene_params: Mapping[str, Any] = field(default_factory=dict)
    reference: str = "path"
    reference_bounces: int | None = None
    views: int | None = None
    resolution: tuple[int, int] | None = None
    profile: str | None = None

    def in_profile(self, profile: str) -> "Job":
        """This job in ``profile`` where it names none (a job's own profile wins)."""
        return self if self.profile is not None else dataclasses.replace(self, profile=profile)

    def describe(self) -> str:
        """``method scene {label}`` for progress and error lines."""
        label = f" {dict(self.label)}" if self.label else ""
        return f"{self.method} {self.scene}{label}"


@dataclass(frozen=True)
class Outputs:
    """Files a job writes besides the store: per-view images and its JSON summary.

    Attributes
    ----------
    out_dir : Path, optional
        Root of the images (``<out>/<method>/<scene>-<variant>/<light>/viewNN.*``) and of
        ``summary.json``; None writes no image.
    json_path : Path, optional
        The JSON summary here too (``--json``).
    """

    out_dir: Path | None = None
    json_path: Path | None = None

    @property
    def writes_files(self) -> bool:
        return self.out_dir is not None or self.json_path is not None


#: A job that writes nothing but its rows.
NO_OUTPUTS = Outputs()
