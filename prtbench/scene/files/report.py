"""What importing an asset file did (:class:`ImportReport`)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class ImportReport:
    """What importing a file did, for ``prtbench scene info``.

    Attributes
    ----------
    path : str
    sha256 : str
        Hash of the file and its sidecar files.
    sidecars : list of str
        Sidecar files hashed with it.
    degenerate_faces, duplicate_faces, non_manifold_edges : int
        Faces removed, and edges shared by more than two faces (kept).
    normals_computed : int
        Objects whose vertex normals were computed (the file had none).
    skipped : list of str
        Non-triangle geometry left out (point clouds, lines).
    warnings : list of str
        Ignored features (emissive, vertex colours, …).
    cameras : int
        Views taken from the file's cameras.
    """

    path: str
    sha256: str
    sidecars: list[str] = field(default_factory=list)
    degenerate_faces: int = 0
    duplicate_faces: int = 0
    non_manifold_edges: int = 0
    normals_computed: int = 0
    skipped: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    cameras: int = 0
