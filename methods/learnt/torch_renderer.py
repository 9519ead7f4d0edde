"""Torch renderer of the learnt transfer (thesis §4.1.4.2 "CUDA", fig. 4.4).

Per frame: a GL pass writes G-buffers (world position + front/back flag, normal + sub-scene
index, kd + s, ks); they are read back to the host and moved to the torch device (the thesis
maps GL textures into CUDA without a copy through PyCUDA; plain torch has no GL interop, so
this path pays GL → host → device, and it is timed); the covered front-facing pixels are packed,
each sub-scene's network runs on its pixels, the transfer is combined with the light (TPFL
matrix, or TP) and shaded with the Phong BRDF exactly as ``prt_shading.glsl`` does, the result
is unpacked into the frame and copied back into a GL texture, as displaying it would require.
CUDA where torch sees it, CPU here.
"""

from __future__ import annotations

import math

import numpy as np

from methods.learnt import glsl
from methods.learnt.model import LearntModel
from methods.learnt.network import TorchNetwork, resolve_device
from methods.learnt.renderer import LearntGLBase
from prtbench.api.method import FrameTimes, wall_frame_times
from prtbench.render.prt_shading import tpfl_matrix_rgb
from prtbench.transport.sh import triple_product_tensor


def sh_eval_torch(torch, dirs, bands: int):
    """Real SH (prtbench.transport.sh convention) of ``bands`` bands at unit ``dirs`` (P, 3): (P, n²).

    The recurrence of ``sh.glsl`` / ``prtbench.transport.sh.eval_sh`` (normalised Legendre functions and
    Re/Im of (x + iy)^m), vectorised over pixels.
    """
    x, y, z = dirs[:, 0], dirs[:, 1], dirs[:, 2]
    out = [None] * (bands * bands)
    re, im = torch.ones_like(z), torch.zeros_like(z)
    qmm = torch.full_like(z, 0.28209479177387814)
    for m in range(bands):
        if m > 0:
            qmm = qmm * math.sqrt((2 * m + 1) / (2 * m))
            re, im = re * x - im * y, re * y + im * x
        q_prev2, q_prev = torch.zeros_like(z), qmm
        for l in range(m, bands):
            if l == m:
                q = qmm
            elif l == m + 1:
                q = math.sqrt(2 * m + 3) * z * qmm
            else:
                a = math.sqrt((4 * l * l - 1) / (l * l - m * m))
                b = math.sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1))
                q = a * (z * q_prev - b * q_prev2)
            if l > m:
                q_prev2, q_prev = q_prev, q
            centre = l * (l + 1)
            if m == 0:
                out[centre] = q
            else:
                out[centre + m] = math.sqrt(2.0) * q * re
                out[centre - m] = math.sqrt(2.0) * q * im
    return torch.stack(out, dim=1)


def phong_zonal_torch(torch, s, bands: int):
    """g_l(s) (P, bands) of the normalised Phong lobe, the recurrence of prt_shading.glsl."""
    ratios = [torch.ones_like(s)]
    if bands > 1:
        ratios.append((s + 1.0) / (s + 2.0))
    for l in range(2, bands):
        ratios.append((s - l + 2.0) / (s + l + 1.0) * ratios[l - 2])
    norms = [math.sqrt((2 * l + 1) / (4 * math.pi)) for l in range(bands)]
    return torch.stack([r * c for r, c in zip(ratios, norms)], dim=1)


def shade_torch(torch, transfer, light_matrix, kd, ks, s, normals, wo, bands: int):
    """Outgoing radiance (P, 3) from transfer (P, n²) and M (n², n², 3): H = T·M, then
    kd/π·√(4π)·H_0 + ks·Σ_l √(4π/(2l+1)) g_l(s) Σ_m H_lm Y_lm(r) (prt_shading.glsl)."""
    incident = torch.einsum("pi,ikc->pkc", transfer, light_matrix)
    radiance = kd / math.pi * (math.sqrt(4 * math.pi) * incident[:, 0, :])
    glossy = (ks > 0).any(dim=1)
    if bool(glossy.any()):
        rows = glossy.nonzero()[:, 0]
        n, w = normals[rows], wo[rows]
        mirror = 2.0 * (n * w).sum(dim=1, keepdim=True) * n - w
        y = sh_eval_torch(torch, mirror / mirror.norm(dim=1, keepdim=True), bands)
        l_of = torch.as_tensor([l for l in range(bands) for _ in range(2 * l + 1)],
                               device=transfer.device)
        kernel = torch.sqrt(4 * math.pi / (2 * l_of.to(transfer.dtype) + 1))
        g = phong_zonal_torch(torch, s[rows], bands)[:, l_of] * kernel
        radiance[rows] += ks[rows] * torch.einsum("pk,pkc->pc", g * y, incident[rows])
    return radiance


class TorchRenderer(LearntGLBase):
    """GL G-buffer -> torch network on covered pixels -> TP/TPFL shading (thesis §4.1.4.2)."""

    def __init__(self, scene, model: LearntModel, config, *, width: int, height: int):
        import torch

        self.torch = torch
        self.device = resolve_device(config.device)
        self.product = config.product
        super().__init__(scene, model, width=width, height=height,
                         fragment_shader="learnt_gbuffer.frag", defines={},
                         include_dir=glsl.include_dir(None, None, model.partition),
                         attachments=4, depth_prepass=False)
        self.nets = [TorchNetwork(net, model.spec, self.device) for net in model.networks]
        self.display = self.ctx.texture((width, height), 4, dtype="f4")
        self._resident = [self.display]
        self._light_key, self._light_matrix = None, None
        if self.device != "cpu":
            self.renderer_string = (f"{self.renderer_string} + torch "
                                    f"{torch.cuda.get_device_name(self.device)}")
        else:
            self.renderer_string = (f"{self.renderer_string} + torch CPU "
                                    f"({torch.get_num_threads()} threads)")
        bands = model.spec.bands
        self.weight_bytes = 4 * model.spec.n_parameters() * len(model.networks)
        self.light_bytes = 4 * bands**4 * 3

    def _bind(self, view, light) -> None:
        pass  # the G-buffer pass needs only the camera

    def _matrix(self, light):
        """M = Σ_j Γ_ijk L_j on the device (n², n², 3); recomputed on a light change.

        ``product=tp`` contracts the triple-product tensor with the light every frame (the
        order that is cheapest for a batch of pixels); ``tpfl`` keeps M per light.
        """
        torch, bands = self.torch, self.model.spec.bands
        if self.product == "tp":

            if not hasattr(self, "_gamma"):
                gamma = np.array(triple_product_tensor(bands), np.float32)  # a writable copy
                self._gamma = torch.as_tensor(gamma, device=self.device)
            coeffs = torch.as_tensor(light.sh(bands), dtype=torch.float32, device=self.device)
            return torch.einsum("ijk,jc->ikc", self._gamma, coeffs)
        key = light.content_hash()
        if key != self._light_key:

            self._light_matrix = torch.as_tensor(tpfl_matrix_rgb(light.sh(bands), bands),
                                                 device=self.device)
            self._light_key = key
        return self._light_matrix

    def _frame(self, view, light) -> np.ndarray:
        """One full frame; returns the (H, W, 3) image (GL row order: bottom row first)."""
        torch = self.torch
        self._draw_geometry(view, light)
        w, h = self.width, self.height
        # GL -> host (the four G-buffers) -> device.
        host = np.stack([np.frombuffer(self.target.fbo.read(components=4, attachment=i,
                                                            dtype="f4", alignment=1),
                                       np.float32).reshape(h * w, 4) for i in range(4)])
        gbuf = torch.from_numpy(host).to(self.device)
        with torch.no_grad():
            covered = (gbuf[0, :, 3] > 0).nonzero()[:, 0]  # front faces; back faces stay 0
            packed = gbuf[:, covered]  # pack: the network sees covered pixels only
            p, n, group = packed[0, :, :3], packed[1, :, :3], packed[1, :, 3].round().long()
            transfer = torch.empty((len(covered), self.model.spec.n_outputs), device=self.device)
            for g, net in enumerate(self.nets):
                rows = (group == g).nonzero()[:, 0] if len(self.nets) > 1 else None
                if rows is None:
                    transfer = net.transfer(p, n)
                elif len(rows):
                    transfer[rows] = net.transfer(p[rows], n[rows])
            wo = torch.as_tensor(np.asarray(view.eye, np.float32), device=self.device) - p
            wo = wo / wo.norm(dim=1, keepdim=True)
            radiance = shade_torch(torch, transfer, self._matrix(light), packed[2, :, :3],
                                   packed[3, :, :3], packed[2, :, 3], n, wo,
                                   self.model.spec.bands)
            frame = torch.zeros((h * w, 4), device=self.device)
            frame[covered, :3] = radiance  # unpack
            frame[:, 3] = 1.0
            image = frame.cpu().numpy()  # device -> host
        self.display.write(image.tobytes())  # host -> GL, where a viewer would show it
        return image.reshape(h, w, 4)[..., :3]

    def render(self, view, light) -> np.ndarray:
        return np.ascontiguousarray(self._frame(view, light)[::-1])

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        """Wall time of whole frames (GL pass, transfers, network, shading), synchronised.

        GL timer queries would only see the G-buffer pass, so the torch path is timed on the
        host clock around complete frames, with glFinish and a CUDA synchronisation.
        """
        torch = self.torch

        def frame() -> None:
            self._frame(view, light)
            self.ctx.finish()
            if self.device != "cpu":
                torch.cuda.synchronize()

        return wall_frame_times(frame, warmup=max(int(warmup), 1), frames=frames,
                                renderer=self.renderer_string, source="wall+sync")

    def memory_bytes(self) -> int:
        # Resident weights (float32) and the light matrix, as for the GLSL path.
        return int(self.weight_bytes + self.light_bytes)
