"""Code shared by several method families (never imported through a private name).

* :mod:`.materials`: the material checks methods share (constant kd, glossy Phong);
* :mod:`.atlas`: the transfer-texture atlas (UV charts, texel G-buffer, normal maps, dilation)
  used by the texture, wavelet-texture and lightmap families.
"""
