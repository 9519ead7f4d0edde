"""Non-linear approximation: the k lighting coefficients kept in a frame (Ng 2003 §4).

Linear approximation keeps a fixed set of basis functions (the first n² SH); non-linear
approximation keeps, for each light (each frame), the k wavelet coefficients that matter most
and drops the rest. "Matter most" is a rule:

* ``magnitude``: the largest ``|L_i|`` — optimal in L² for an orthonormal basis (the dropped
  energy Σ L_i² is the smallest possible for k terms);
* ``area``: the largest ``|L_i|·A_i``, A_i the solid angle of the coefficient's support
  (:func:`prtbench.transport.wavelet.haar.support_solid_angles`), Ng 2003's choice: diffuse transport
  is smooth, so coarse wavelets (large supports) meet large transport coefficients;
* ``transport``: the largest ``|L_i|·w_i``, w_i a per-coefficient transport weight, e.g. the
  mean over vertices of ``|T_vi|`` (the expected contribution of term i to a pixel).

An RGB coefficient's magnitude is the Euclidean norm of its three channels, so one set of k
terms (each with an RGB value) serves all channels.
"""

from __future__ import annotations

import numpy as np

from prtbench.api.errors import InvalidInputError

SELECTION_RULES = ("magnitude", "area", "transport")


def scores(coeffs: np.ndarray, *, rule: str = "area", support: np.ndarray | None = None,
           transport_weight: np.ndarray | None = None) -> np.ndarray:
    """The score each coefficient is ranked by, (M,) float64.

    Parameters
    ----------
    coeffs : ndarray, shape (M,) or (M, C)
        Flat lighting coefficients (C channels).
    rule : {"magnitude", "area", "transport"}
    support : ndarray, shape (M,), optional
        Support solid angles; required by ``area``.
    transport_weight : ndarray, shape (M,), optional
        Non-negative transport weights; required by ``transport``.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim not in (1, 2):
        raise InvalidInputError(f"lighting coefficients shape {c.shape}; accepted: (M,) or (M, C)")
    magnitude = np.abs(c) if c.ndim == 1 else np.sqrt(np.einsum("mc,mc->m", c, c))
    if rule == "magnitude":
        return magnitude
    weight = {"area": support, "transport": transport_weight}.get(rule, None)
    if rule not in SELECTION_RULES:
        raise InvalidInputError(f"selection rule '{rule}'; accepted: {', '.join(SELECTION_RULES)}")
    if weight is None:
        need = "support" if rule == "area" else "transport_weight"
        raise InvalidInputError(f"selection rule '{rule}' needs {need} (one value per coefficient)")
    weight = np.asarray(weight, dtype=np.float64).reshape(-1)
    if weight.shape != magnitude.shape:
        raise InvalidInputError(f"{rule} weights have {weight.size} values for "
                                f"{magnitude.size} coefficients; accepted: one per coefficient")
    return magnitude * weight


def select_terms(coeffs: np.ndarray, k: int, *, rule: str = "area",
                 support: np.ndarray | None = None,
                 transport_weight: np.ndarray | None = None) -> np.ndarray:
    """Flat indices of the k highest-scoring coefficients, (k,) int64, ascending.

    Parameters
    ----------
    coeffs : ndarray, shape (M,) or (M, C)
    k : int
        1 <= k <= M.
    rule, support, transport_weight
        See :func:`scores`.

    Notes
    -----
    O(M) per call (a partial partition, not a sort): it runs every frame.
    """
    s = scores(coeffs, rule=rule, support=support, transport_weight=transport_weight)
    m = len(s)
    if isinstance(k, bool) or int(k) != k or not 1 <= k <= m:
        raise InvalidInputError(f"light_terms k={k!r}; accepted: integers 1..{m} (the "
                                "number of wavelet coefficients of the cubemap)")
    k = int(k)
    if k == m:
        return np.arange(m, dtype=np.int64)
    picked = np.argpartition(-s, k - 1)[:k]
    return np.sort(picked).astype(np.int64)


def approximate(coeffs: np.ndarray, k: int, **rule) -> np.ndarray:
    """``coeffs`` with all but the k selected terms set to zero (same shape, float64)."""
    c = np.asarray(coeffs, dtype=np.float64)
    out = np.zeros_like(c)
    keep = select_terms(c, k, **rule)
    out[keep] = c[keep]
    return out
