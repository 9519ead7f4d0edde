"""The lightmap renderer: the atlas mesh with a depth pre-pass, one texture fetch per
coefficient, the decode and the irradiance at the pixel's (normal-mapped) normal.

The lightmap lives in one ``sampler2DArray``: layer s·K + k holds coefficient k (RGB, and
RGBM's multiplier in alpha) of texture set s. An artifact baked for ``bake_light`` is uploaded
as it is; otherwise each new light is folded into the texels on the CPU
(:func:`methods.lightmap.encoding.fold`) and written into the same texture, once per light.
"""

from __future__ import annotations

import numpy as np

from methods.common.atlas.raster import AtlasRenderer
from methods.lightmap import SHADER_DIR
from methods.lightmap.encoding import ENCODINGS, SH_BANDS, encode, fold, hbasis_matrix
from prtbench.api.errors import InvalidInputError
from prtbench.transport.sh import clamped_cosine_zonal

#: Storage → the STORAGE define of lightmap.frag.
STORAGE_DEFINES = {"float16": 0, "rgbm": 1, "scaled8": 2}


def layer_stack(stored: np.ndarray, filled: np.ndarray) -> np.ndarray:
    """Per-filled-texel RGBA coefficients (F, K, 4) → texture layers (S·K, R, R, 4).

    ``filled`` (S, R, R) marks the F texels in flat order; the others hold zeros.
    """
    s, r, _ = filled.shape
    k = stored.shape[1]
    full = np.zeros((s * r * r, k, 4), stored.dtype)
    full[np.flatnonzero(filled.reshape(-1))] = stored
    return np.ascontiguousarray(full.reshape(s, r, r, k, 4).transpose(0, 3, 1, 2, 4)
                                .reshape(s * k, r, r, 4))


class LightmapRenderer(AtlasRenderer):
    """Draws the lightmap of one light (baked in the artifact, or folded here per light)."""

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact, config, *, width: int, height: int):
        arrays, meta = artifact.arrays, artifact.meta
        self.encoding, self.storage = str(meta["encoding"]), str(meta["storage"])
        self.bake_bands = int(meta["bake_bands"])
        self.count = ENCODINGS[self.encoding]
        sh_bands = SH_BANDS.get(self.encoding, 0)
        defines = {"COEFFS": self.count, "STORAGE": STORAGE_DEFINES[self.storage],
                   "ENCODING_SH": int(sh_bands > 0), "ENCODING_HBASIS": int(
                       self.encoding.startswith("hbasis"))}
        if sh_bands:
            defines["SH_BANDS"] = sh_bands
        super().__init__(scene, arrays, meta, fragment_shader="lightmap.frag", defines=defines,
                         width=width, height=height)
        self.filled = np.asarray(arrays["filled"], bool)
        self.baked_hash = meta.get("bake_light_hash")
        self.bakes_its_light = self.baked_hash is not None
        self.baked_name = meta.get("bake_light")
        if self.baked_hash is not None:
            layers = arrays["lightmap"]
            self.uniforms = {k: np.asarray(v) for k, v in meta["uniforms"].items()}
        else:
            self.visibility = arrays["visibility"]
            self.normals = arrays["texel_normals"]
            dtype = np.float16 if self.storage == "float16" else np.uint8
            s, r, _ = self.filled.shape
            layers = np.zeros((s * self.count, r, r, 4), dtype)
            self.uniforms = None
        self.folded: str | None = self.baked_hash
        what = f"lightmap ({self.encoding}, {self.count} {self.storage} RGBA layer(s) per set)"
        self.lightmap = self.texture_array(what, layers)
        if sh_bands:
            self.program["zonal"].write(clamped_cosine_zonal(sh_bands).astype(np.float32).tobytes())
        if "hbasis" in self.program:
            self.program["hbasis"].write(hbasis_matrix(self.count).astype(np.float32).tobytes())

    def _check_light(self, light) -> None:
        if self.baked_hash is not None and light.content_hash() != self.baked_hash:
            raise InvalidInputError(
                f"this lightmap bakes light '{self.baked_name}', not '{light.name}'; accepted: "
                f"render with light '{self.baked_name}', or precompute with "
                f"bake_light={light.name} (--set bake_light={light.name}), or bake_light empty "
                "(each light baked when rendered)")

    def fold_light(self, light) -> None:
        """Bake ``light`` into the texture (CPU fold and encode, one upload) unless it is in."""
        key = light.content_hash()
        if key == self.folded:
            return
        coeffs = fold(self.visibility, self.normals, light.sh(self.bake_bands),
                      encoding=self.encoding, bake_bands=self.bake_bands)
        stored, self.uniforms = encode(coeffs, self.storage, encoding=self.encoding,
                                       light=light.name)
        self.lightmap.write(layer_stack(stored, self.filled).tobytes())
        self.folded = key

    def _bind(self, view, light) -> None:
        self.fold_light(light)  # once per light: later frames of the same light only bind
        self.lightmap.use(location=0)
        self.program["lightmap"].value = 0
        u = self.uniforms
        values = {"half_scale": float(u.get("half_scale", 1.0)),
                  "rgbm_range": float(u["rgbm_range"]),
                  "ratio_bound": np.asarray(u["ratio_bound"], np.float32),
                  "scale": np.asarray(u["scale"], np.float32),
                  "bias": np.asarray(u["bias"], np.float32)}
        for name, value in values.items():
            if name not in self.program:  # a storage's unused uniforms are compiled out
                continue
            if isinstance(value, float):
                self.program[name].value = value
            else:
                self.program[name].write(np.ascontiguousarray(value).tobytes())
