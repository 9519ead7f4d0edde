"""The GL G-buffer pass of the neural wavelet transport (training data and renderer alike).

One draw of the merged scene into four RGBA32F attachments (``shaders/nw_gbuffer.frag``):
position + front/back flag, normal + merged triangle index, kd + Phong exponent, ks. Training
pixels and rendered pixels come from this same pass, so the network sees at render time
exactly the inputs it was trained on. Back faces are kept in the buffer with flag −1 and
shaded black (DESIGN.md §4: surfaces are one-sided).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.render import gl
from prtbench.scene.model import Texture

SHADER_DIR = Path(__file__).resolve().parent / "shaders"


def check_constant_materials(method: str, scene) -> None:
    """One-line error for textured kd/ks/s (the G-buffer carries one value per object)."""
    for obj in scene.objects:
        for attr in ("kd", "ks", "shininess"):
            if isinstance(getattr(obj.material, attr), Texture):
                raise InvalidInputError(
                    f"method '{method}' takes a constant {attr} per object, but '{obj.name}' in "
                    f"scene '{scene.name}' has a textured {attr}; accepted: constant kd, ks, "
                    "shininess")


def vertex_attributes(scene) -> dict[str, np.ndarray]:
    """Per-vertex inputs of ``nw_gbuffer.vert`` in merged order."""
    _, normals, _, _ = scene.merged()

    def per_vertex(value, width):
        return np.concatenate([np.broadcast_to(np.asarray(getattr(o.material, value), np.float32)
                                               .reshape(-1)[:width], (o.mesh.n_vertices, width))
                               for o in scene.objects])

    return {"normal": normals, "kd": per_vertex("kd", 3), "ks": per_vertex("ks", 3),
            "shininess": per_vertex("shininess", 1)}


def camera_matrix(scene, view, width: int, height: int) -> bytes:
    """``clip_from_world`` (column-major float32 bytes) with near/far enclosing the scene."""
    lo, hi = scene.bounds()
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    dist = float(np.linalg.norm(np.asarray(view.eye) - centre))
    far = dist + radius * 1.01 + 1e-3
    near = max(dist - radius * 1.01, far * 1e-4)
    m = view.clip_from_camera(width / height, near, far) @ view.camera_from_world()
    return m.T.astype(np.float32).tobytes()


class GBufferPass:
    """Draws the G-buffer of ``scene`` at ``width`` × ``height`` on the shared GL context."""

    def __init__(self, scene, *, width: int, height: int):
        self.scene, self.width, self.height = scene, int(width), int(height)
        self.ctx = gl.create_context()
        self.renderer_string = gl.renderer_string(self.ctx)
        self.program = gl.load_program(self.ctx, "nw_gbuffer.vert", "nw_gbuffer.frag",
                                       search_path=[SHADER_DIR])
        positions, _, faces, _ = scene.merged()
        self.vao = gl.upload_mesh(self.ctx, self.program, positions, faces,
                                  attributes=vertex_attributes(scene))
        self.target = gl.RenderTarget(self.ctx, self.width, self.height, attachments=4)

    def draw(self, view) -> None:
        self.program["clip_from_world"].write(camera_matrix(self.scene, view, self.width,
                                                            self.height))
        self.target.use()
        self.target.clear()
        self.ctx.enable(gl.moderngl.DEPTH_TEST)
        self.ctx.disable(gl.moderngl.CULL_FACE)  # back faces are drawn (and shaded black)
        self.ctx.depth_func = "<"
        self.vao.render()

    def read_gl(self) -> np.ndarray:
        """The four attachments, (4, H·W, 4) float32 in GL row order (bottom row first)."""
        fbo = self.target.fbo
        return np.stack([np.frombuffer(fbo.read(components=4, attachment=i, dtype="f4",
                                                alignment=1), np.float32)
                         .reshape(self.height * self.width, 4) for i in range(4)])

    def read(self, view) -> np.ndarray:
        """Draw ``view`` and return (4, H, W, 4) float32 with row 0 at the top (image order)."""
        self.draw(view)
        g = self.read_gl().reshape(4, self.height, self.width, 4)
        return np.ascontiguousarray(g[:, ::-1])

    def release(self) -> None:
        for buffer in (self.vao.extra or {}).get("buffers", []):
            buffer.release()
        self.vao.release()
        self.program.release()
        self.target.release()


def pixel_rows(gbuffer: np.ndarray, eye) -> dict[str, np.ndarray]:
    """The front-facing covered pixels of a G-buffer (4, …, 4) as flat rows.

    Returns
    -------
    dict
        ``pixel`` (P,) flat index into the image, ``positions``, ``normals``, ``wo``, ``kd``,
        ``ks`` (P, 3) float32, ``shininess`` (P,) float32, ``triangles`` (P,) int64.
    """
    g = gbuffer.reshape(4, -1, 4)
    pixel = np.flatnonzero(g[0, :, 3] > 0)
    pos = g[0, pixel, :3]
    wo = np.asarray(eye, np.float32)[None] - pos
    wo /= np.maximum(np.linalg.norm(wo, axis=1, keepdims=True), 1e-12)
    return {"pixel": pixel.astype(np.int64), "positions": pos.copy(),
            "normals": g[1, pixel, :3].copy(), "wo": wo.astype(np.float32),
            "kd": g[2, pixel, :3].copy(), "ks": g[3, pixel, :3].copy(),
            "shininess": g[2, pixel, 3].copy(),
            "triangles": np.rint(g[1, pixel, 3]).astype(np.int64)}
