"""All-frequency lighting on cubemaps: the cube, the Haar transform and non-linear selection.

DESIGN.md §17. Three nouns, one module each:

* :mod:`~prtbench.transport.wavelet.cubemap`: 6×N×N cubemaps (face/axis convention, exact texel solid
  angles, direction ↔ texel, lat-long lights resampled by integration over each texel);
* :mod:`~prtbench.transport.wavelet.haar`: the orthonormal non-standard 2-D Haar transform per face,
  vectorised over many signals;
* :mod:`~prtbench.transport.wavelet.selection`: the k largest lighting coefficients per frame (by
  magnitude, area-weighted magnitude or transport-weighted magnitude).

and for Ng 2004's changing view: :mod:`~prtbench.transport.wavelet.triple` (Haar triple products
∫ L·V·ρ̃ by the tree algorithm) and :mod:`~prtbench.transport.wavelet.brdf` (the cosine-weighted Phong
BRDF in Haar per (n, ωo), projected per vertex or tabulated); there the transport is V·ρ̃
and the weights live in its BRDF factor ρ̃ (V is a bare visible fraction).

**Where the solid-angle weights live** (one convention for every wavelet method): in the
*transport*. A cubemap light is its texel-mean radiance ``L_t`` (no weights); a transport
cubemap is ``T_t = ∫_texel V(ω) max(n·ω, 0) dω`` (the texel's solid angle folded in). Then
``Σ_t L_t T_t`` is the cubemap integral of ``L·V·cos``, and since the Haar transform is
orthonormal it equals ``Σ_i L̂_i T̂_i`` over all coefficients; keeping fewer terms truncates
that sum.

This package imports only numpy at module level (``prtbench list`` stays instant).
"""

from prtbench.transport.wavelet.cubemap import (
    FACE_FRAMES,
    FACE_NAMES,
    cubemap_lookup,
    directions_to_texels,
    from_lat_long,
    texel_directions,
    texel_solid_angles,
)
from prtbench.transport.wavelet.haar import forward, inverse, support_solid_angles
from prtbench.transport.wavelet.selection import SELECTION_RULES, select_terms

__all__ = ["FACE_FRAMES", "FACE_NAMES", "SELECTION_RULES", "cubemap_lookup",
           "directions_to_texels", "forward", "from_lat_long", "inverse", "select_terms",
           "support_solid_angles", "texel_directions", "texel_solid_angles"]
