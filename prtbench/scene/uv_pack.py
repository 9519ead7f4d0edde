"""xatlas chart packing, run in a child process so that a crash of xatlas cannot take the caller.

xatlas (through its Python binding) crashes natively now and then: a segmentation fault inside
``Atlas.add_mesh`` was seen once in a full test session, and not again in hundreds of packs of
the same meshes in a fresh process. Upstream has several open reports of random crashes on
valid meshes; xatlas runs its chart work on a task scheduler of its own threads. Whatever the
cause, a native crash in the test or benchmark process loses the whole run, so
:func:`pack_atlas` runs the packing in a fresh interpreter (about 0.2 s of start-up, paid once
per mesh content: atlases are cached) and retries it when the child dies of a signal.

The child is this module: ``python -m prtbench.scene.uv_pack IN.npz OUT.npz``. It imports only NumPy
and xatlas.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import xatlas

from prtbench.api.errors import InvalidInputError, PrtbenchError

#: How many times a child killed by a signal is retried before the packing is given up.
ATTEMPTS = 3

#: Exit status of a child whose meshes do not fit (a clear error, not a crash: no retry).
_NO_FIT = 3


class _NoFit(Exception):
    pass


def _pack_in_process(meshes: list[tuple[np.ndarray, np.ndarray, np.ndarray]], resolution: int,
                     padding: int) -> list[dict[str, np.ndarray]]:
    """Run xatlas on ``meshes`` ((positions, faces, normals) each) packed into one texture."""

    def build(texels_per_unit: float) -> "xatlas.Atlas":
        atlas = xatlas.Atlas()
        for positions, faces, normals in meshes:
            atlas.add_mesh(positions, faces, normals)
        pack = xatlas.PackOptions()
        pack.resolution = resolution
        pack.padding = padding
        pack.bilinear = True
        pack.texels_per_unit = texels_per_unit
        atlas.generate(pack_options=pack)
        return atlas

    # With texels_per_unit = 0 xatlas estimates a scale but may return a larger texture; rescale
    # that estimate to the requested side, then shrink until every chart fits in one texture.
    atlas = build(0.0)
    tpu = atlas.texels_per_unit * resolution / max(atlas.width, atlas.height, 1)
    for _ in range(40):
        atlas = build(tpu)
        if atlas.atlas_count == 1 and atlas.width == resolution and atlas.height == resolution:
            break
        tpu *= 0.92
    else:  # pragma: no cover - xatlas always fits eventually at a small enough scale
        raise _NoFit(f"could not pack the atlas into {resolution}² texels")
    out = []
    for k in range(len(meshes)):
        vmap, faces, uvs = atlas[k]
        out.append({"vertex_map": vmap.astype(np.int64), "faces": faces.astype(np.int32),
                    "uvs": np.clip(uvs, 0.0, 1.0).astype(np.float32),
                    "utilization": np.array(atlas.utilization)})
    return out


def pack_atlas(meshes: list[tuple[np.ndarray, np.ndarray, np.ndarray]], *, resolution: int,
               padding: int) -> list[dict[str, np.ndarray]]:
    """Pack ``meshes`` into one ``resolution``² texture with xatlas, in a child process.

    Parameters
    ----------
    meshes : list of (positions (V, 3), faces (F, 3), normals (V, 3))
    resolution, padding : int
        Texture side and empty texels between charts.

    Returns
    -------
    list of dict
        Per mesh: ``vertex_map`` (V',) int64 source vertex of each atlas vertex, ``faces``
        (F, 3) int32, ``uvs`` (V', 2) float32 in [0, 1], ``utilization`` () fraction of
        texels covered.

    Raises
    ------
    InvalidInputError
        The charts do not fit the texture at any scale.
    PrtbenchError
        xatlas crashed in all :data:`ATTEMPTS` children, or failed with a Python error.
    """

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (str(Path(__file__).resolve().parents[2]), os.environ.get("PYTHONPATH"))
        if p)}
    with tempfile.TemporaryDirectory(prefix="prtbench-uv-") as tmp:
        source, result = Path(tmp) / "meshes.npz", Path(tmp) / "atlas.npz"
        arrays = {"resolution": np.array(resolution), "padding": np.array(padding),
                  "count": np.array(len(meshes))}
        for k, (positions, faces, normals) in enumerate(meshes):
            arrays[f"positions_{k}"] = np.ascontiguousarray(positions, np.float32)
            arrays[f"faces_{k}"] = np.ascontiguousarray(faces, np.uint32)
            arrays[f"normals_{k}"] = np.ascontiguousarray(normals, np.float32)
        np.savez(source, **arrays)
        deaths = []
        for _ in range(ATTEMPTS):
            child = subprocess.run([sys.executable, "-m", "prtbench.scene.uv_pack", str(source),
                                    str(result)], env=env, capture_output=True, text=True)
            if child.returncode == 0:
                with np.load(result) as flat:
                    return [{name: flat[f"{name}_{k}"] for name in
                             ("vertex_map", "faces", "uvs", "utilization")}
                            for k in range(len(meshes))]
            last = (child.stderr.strip().splitlines() or ["(no output)"])[-1]
            if child.returncode == _NO_FIT:
                raise InvalidInputError(last)
            if child.returncode > 0:  # a Python error: the same input would fail again
                raise PrtbenchError(f"xatlas packing failed: {last}")
            deaths.append(_signal_name(-child.returncode))
    raise PrtbenchError(f"xatlas crashed packing {len(meshes)} mesh(es) into {resolution}² "
                        f"texels in each of {ATTEMPTS} attempts ({', '.join(deaths)})")


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def _main(source: str, result: str) -> int:
    with np.load(source) as flat:
        meshes = [(flat[f"positions_{k}"], flat[f"faces_{k}"], flat[f"normals_{k}"])
                  for k in range(int(flat["count"]))]
        resolution, padding = int(flat["resolution"]), int(flat["padding"])
    try:
        parts = _pack_in_process(meshes, resolution, padding)
    except _NoFit as exc:
        print(exc, file=sys.stderr)
        return _NO_FIT
    np.savez(result, **{f"{name}_{k}": value for k, part in enumerate(parts)
                        for name, value in part.items()})
    return 0


if __name__ == "__main__":
    sys.exit(_main(*sys.argv[1:]))
