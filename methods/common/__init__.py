"""Code shared by several method families (never imported through a private name).

* :mod:`.materials`: the material checks methods share (constant kd, glossy Phong);
* :mod:`.atlas`: the transfer-texture atlas (UV charts, texel G-buffer, normal maps, dilation)
  used by the texture, wavelet-texture, AO / bent-normal texture and lightmap families;
* :mod:`.sphere_rays`: uniform sphere rays from points (visibility SH, back-face fractions,
  per-ray reductions) used by the lightmap and probe-volume families;
* :mod:`.residency`: a ``memory_breakdown`` naming a method's own GL data beside everything
  else its renderer holds (the AO / bent-normal, lightmap and probe-volume renderers).
"""
