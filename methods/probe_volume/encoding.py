"""The probe pool's texel layouts: what each RGBA texel of each pool texture holds, the numpy
encode (:func:`encode`) and decode (:func:`decode`), and the GLSL decode generated from the
same table (:func:`decode_glsl`), so the shader and numpy cannot drift apart.

A probe holds K coefficients of C channels: RGB radiance (``fixed``: SH L1 / L2 of the baked
radiance, or the ambient cube's six irradiance colours) or a mono transfer (``relight``: SH
L1 / L2 of the sky visibility, or the ambient cube's six cosine-weighted visibilities).

``engine`` storage is the shipped quantised layout:

* SH, RGB (Unity's ProbeBrickPool): L0 and L1 in exactly 16 bytes, an RGBA16F texel
  (L0.rgb, L1_R.x) and two RGBA8 texels (L1_G.xyz, L1_R.y) and (L1_B.xyz, L1_R.z); L2 in 16
  more, four RGBA8 texels of the 15 values (and one unused). Every L1 and L2 value is stored
  as its ratio to the same channel's L0, as 0.5 + ratio / (2·bound), bound the largest ratio a
  non-negative function can have (max|Y_k| / Y_0: √3 for l = 1, √15/2 and √5 for l = 2);
* SH, mono (Unity's sky occlusion): L0 and L1 as one RGBA16F texel (8 bytes), L2 as ratios in
  two RGBA8 texels (16 bytes in all);
* ambient cube, RGB (Half-Life 2's ColorRGBExp32): each colour as an RGBA8 texel of an 8-bit
  mantissa per channel and a shared exponent (24 bytes); mono: the six visibilities in [0, 1]
  as 8-bit unorm in two RGBA8 texels (8 bytes).

``float16`` storage puts value 4t + s of the probe's K·C values (value 3k + c for RGB) in
channel s of RGBA16F texture t.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

#: SH bands of each SH encoding, and the ambient cube's six axes (+x, −x, +y, −y, +z, −z).
SH_ENCODING_BANDS = {"l1": 2, "l2": 3}
CUBE_AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                     np.float64)
#: Coefficients per probe of each encoding.
COEFFICIENTS = {"l1": 4, "l2": 9, "ambient-cube": 6}
#: Largest |c_k / c_0| of a non-negative function (max|Y_k| / Y_0), in the flat SH order.
RATIO_BOUNDS = (1.0,) + (math.sqrt(3.0),) * 3 + (math.sqrt(15.0) / 2,) * 2 + (math.sqrt(5.0),) + \
    (math.sqrt(15.0) / 2,) * 2

#: A texel slot: (kind, coefficient, channel); kinds "raw" (the value), "ratio" (0.5 + ratio
#: to coefficient 0's same channel / (2·bound)), "unorm" (a value in [0, 1]), "mantissa" and
#: "exponent" (RGBE: channel c's 8-bit mantissa, the colour's shared exponent + 128, /255),
#: "pad" (unused).
Slot = tuple[str, int, int]


@lru_cache(maxsize=32)
def layout(encoding: str, storage: str, channels: int) -> tuple[tuple[str, tuple[Slot, ...]], ...]:
    """The pool textures of a probe: ((dtype, four slots), ...), dtype "f2" (RGBA16F) or "u1"
    (RGBA8 unorm)."""
    k = COEFFICIENTS[encoding]
    pad: Slot = ("pad", 0, 0)
    if storage == "float16":
        values = [("raw", i // channels, i % channels) for i in range(k * channels)]
        values += [pad] * (-len(values) % 4)
        return tuple(("f2", tuple(values[t:t + 4])) for t in range(0, len(values), 4))
    if encoding == "ambient-cube":
        if channels == 3:
            return tuple(("u1", (("mantissa", d, 0), ("mantissa", d, 1), ("mantissa", d, 2),
                                 ("exponent", d, 0))) for d in range(6))
        unorm = [("unorm", d, 0) for d in range(6)] + [pad, pad]
        return (("u1", tuple(unorm[:4])), ("u1", tuple(unorm[4:])))
    if channels == 3:  # x, y, z of l = 1 are flat coefficients 3, 1, 2
        textures = [("f2", (("raw", 0, 0), ("raw", 0, 1), ("raw", 0, 2), ("ratio", 3, 0))),
                    ("u1", (("ratio", 3, 1), ("ratio", 1, 1), ("ratio", 2, 1), ("ratio", 1, 0))),
                    ("u1", (("ratio", 3, 2), ("ratio", 1, 2), ("ratio", 2, 2), ("ratio", 2, 0)))]
    else:
        textures = [("f2", (("raw", 0, 0), ("raw", 1, 0), ("raw", 2, 0), ("raw", 3, 0)))]
    if k > 4:
        rest = [("ratio", i // channels + 4, i % channels) for i in range(5 * channels)]
        rest += [pad] * (-len(rest) % 4)
        textures += [("u1", tuple(rest[t:t + 4])) for t in range(0, len(rest), 4)]
    return tuple(textures)


def bytes_per_probe(encoding: str, storage: str, channels: int) -> int:
    """Pool bytes of one probe: 8 per RGBA16F texel, 4 per RGBA8 texel."""
    return sum(8 if dtype == "f2" else 4 for dtype, _ in layout(encoding, storage, channels))


def encode(values: np.ndarray, *, encoding: str, storage: str) -> list[np.ndarray]:
    """Per-probe coefficients (P, K, C) → one (P, 4) array per pool texture (float16/uint8).

    Ratios are clipped to their bound (a truncated or ringing SH can pass it slightly) and use
    0 where coefficient 0 of the channel is not positive.
    """
    v = np.asarray(values, np.float64)
    p, k, channels = v.shape
    base = v[:, 0, :]
    safe = np.where(base > 0.0, base, np.inf)
    peak = np.max(np.maximum(v, 0.0), axis=2)  # (P, K) brightest channel of each colour
    exponent = np.where(peak > 0.0, np.ceil(np.log2(np.maximum(peak, 1e-300))), -128.0)
    exponent = np.clip(exponent, -128.0, 127.0)
    out = []
    for dtype, slots in layout(encoding, storage, channels):
        texel = np.zeros((p, 4))
        for s, (kind, coeff, channel) in enumerate(slots):
            if kind == "raw":
                texel[:, s] = v[:, coeff, channel]
            elif kind == "ratio":
                bound = RATIO_BOUNDS[coeff]
                ratio = np.clip(v[:, coeff, channel] / safe[:, channel], -bound, bound)
                texel[:, s] = 0.5 + ratio / (2.0 * bound)
            elif kind == "unorm":
                texel[:, s] = v[:, coeff, channel]
            elif kind == "mantissa":
                texel[:, s] = np.maximum(v[:, coeff, channel], 0.0) / np.exp2(exponent[:, coeff])
            elif kind == "exponent":
                texel[:, s] = (exponent[:, coeff] + 128.0) / 255.0
        if dtype == "f2":
            out.append(texel.astype(np.float16))
        else:
            out.append(np.rint(np.clip(texel, 0.0, 1.0) * 255.0).astype(np.uint8))
    return out


def decode(textures: list[np.ndarray], *, encoding: str, storage: str,
           channels: int) -> np.ndarray:
    """The numpy twin of the generated GLSL decode: (P, 4) textures → (P, K, C) float64."""
    k = COEFFICIENTS[encoding]
    texels = [np.asarray(t, np.float64) / (255.0 if np.asarray(t).dtype == np.uint8 else 1.0)
              for t in textures]
    out = np.zeros((len(texels[0]), k, channels))
    deferred = []
    for texel, (_, slots) in zip(texels, layout(encoding, storage, channels)):
        for s, (kind, coeff, channel) in enumerate(slots):
            if kind in ("raw", "unorm"):
                out[:, coeff, channel] = texel[:, s]
            elif kind == "ratio":
                deferred.append((texel[:, s], coeff, channel))
            elif kind == "mantissa":
                exponent_slot = 3
                out[:, coeff, channel] = texel[:, s] * np.exp2(
                    np.rint(texel[:, exponent_slot] * 255.0) - 128.0)
    for value, coeff, channel in deferred:  # after coefficient 0 is known
        out[:, coeff, channel] = (value - 0.5) * 2.0 * RATIO_BOUNDS[coeff] * out[:, 0, channel]
    return out


def decode_glsl(encoding: str, storage: str, channels: int) -> str:
    """``probe_decode.glsl``: ``void probe_coefficients(ivec3 texel, out COEFF c[K])`` reading
    the pool samplers ``pool0`` … (the same table as :func:`decode`)."""
    textures = layout(encoding, storage, channels)
    k = COEFFICIENTS[encoding]
    kind_of = "vec3" if channels == 3 else "float"
    lines = ["// Generated by methods.probe_volume.encoding.decode_glsl: do not edit.",
             f"#define POOL_TEXTURES {len(textures)}",
             *[f"uniform sampler3D pool{t};" for t in range(len(textures))],
             f"void probe_coefficients(ivec3 texel, out {kind_of} c[{k}]) {{"]
    lines += [f"    vec4 t{t} = texelFetch(pool{t}, texel, 0);" for t in range(len(textures))]

    def target(coeff: int, channel: int) -> str:
        return f"c[{coeff}]" + ("." + "rgb"[channel] if channels == 3 else "")

    ratios = []
    for t, (_, slots) in enumerate(textures):
        for s, (kind, coeff, channel) in enumerate(slots):
            value = f"t{t}.{'xyzw'[s]}"
            if kind in ("raw", "unorm"):
                lines.append(f"    {target(coeff, channel)} = {value};")
            elif kind == "mantissa":
                lines.append(f"    {target(coeff, channel)} = {value} * "
                             f"exp2(round(t{t}.w * 255.0) - 128.0);")
            elif kind == "ratio":
                ratios.append(f"    {target(coeff, channel)} = ({value} - 0.5) * "
                              f"{2.0 * RATIO_BOUNDS[coeff]!r} * {target(0, channel)};")
    return "\n".join(lines + ratios + ["}", ""])
