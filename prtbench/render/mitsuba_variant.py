"""Which Mitsuba 3 variant renders the references: ``cuda_ad_rgb`` where a GPU is present, else
``llvm_ad_rgb`` (needs a libLLVM Mitsuba accepts: Debian's ``libllvm19``, found through
``DRJIT_LIBLLVM_PATH``), else ``scalar_rgb`` (DESIGN.md §6); ``PRTBENCH_MITSUBA_VARIANT`` names
one, checked before any work.
"""

from __future__ import annotations

import logging
import os

import numpy as np

from prtbench.api.errors import InvalidInputError, PrtbenchError

log = logging.getLogger(__name__)

#: Environment variable naming the variant (checked before any work).
VARIANT_ENV = "PRTBENCH_MITSUBA_VARIANT"
#: Tried in this order when it is unset.
VARIANT_ORDER = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
DEBIAN_LIBLLVM = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"
_chosen: dict[str | None, str] = {}


def _try_variant(name: str) -> None:
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(name)
    # A backend can import yet fail on first use (no GPU, unusable libLLVM): run a kernel.
    probe = mi.Float(1.0) + mi.Float(2.0)
    dr.eval(probe)
    if abs(float(np.asarray(probe).ravel()[0]) - 3.0) > 1e-6:
        raise RuntimeError(f"variant {name} computed {probe}")


def select_variant() -> str:
    """Activate and return the Mitsuba variant for references (see module docstring).

    Raises
    ------
    InvalidInputError
        If ``$PRTBENCH_MITSUBA_VARIANT`` names a variant that is unknown or unusable here.
    """
    override = os.environ.get(VARIANT_ENV) or None
    if override in _chosen:
        import mitsuba as mi

        if mi.variant() != _chosen[override]:
            mi.set_variant(_chosen[override])
        return _chosen[override]
    if "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(DEBIAN_LIBLLVM):
        os.environ["DRJIT_LIBLLVM_PATH"] = DEBIAN_LIBLLVM  # read when drjit first starts LLVM
    import mitsuba as mi

    if override is not None:
        known = [v for v in mi.variants() if v.endswith("_rgb")]
        if override not in known:
            raise InvalidInputError(
                f"{VARIANT_ENV}={override!r} is not a Mitsuba RGB variant; accepted (working "
                f"here): {', '.join(usable_variants()) or '(none)'}")
        try:
            _try_variant(override)
        except Exception as exc:  # noqa: BLE001 - mitsuba raises ImportError/RuntimeError
            raise InvalidInputError(
                f"{VARIANT_ENV}={override!r} is not usable here ({one_line(exc)}); "
                f"accepted (working here): {', '.join(usable_variants()) or '(none)'}") from None
        chosen = override
    else:
        chosen = ""
        for name in VARIANT_ORDER:
            try:
                _try_variant(name)
            except Exception as exc:  # noqa: BLE001
                log.info("mitsuba variant %s unavailable: %s", name, one_line(exc))
                continue
            chosen = name
            break
        if not chosen:
            raise PrtbenchError(f"no Mitsuba variant works here; tried {', '.join(VARIANT_ORDER)}")
    log.info("mitsuba variant for references: %s", chosen)
    _chosen[override] = chosen
    return chosen


def usable_variants() -> list[str]:
    """The RGB variants of :data:`VARIANT_ORDER` (then any other compiled one) that run here."""
    import mitsuba as mi

    compiled = [v for v in mi.variants() if v.endswith("_rgb")]
    order = [v for v in VARIANT_ORDER if v in compiled] + \
        [v for v in compiled if v not in VARIANT_ORDER]
    working = []
    for name in order:
        try:
            _try_variant(name)
        except Exception:  # noqa: BLE001 - a backend that cannot start is simply not listed
            continue
        working.append(name)
    return working


def check_variant() -> str:
    """Validate the reference variant before any work; returns the variant name.

    The runner's ``prepare()`` calls this so that a bad ``$PRTBENCH_MITSUBA_VARIANT`` (unknown,
    or not usable on this machine) is a one-line error before the precompute, not after it.
    It activates the variant (:func:`select_variant`), which the reference needs anyway.

    Raises
    ------
    InvalidInputError
        ``$PRTBENCH_MITSUBA_VARIANT`` is unknown or unusable (names it and the working ones).
    PrtbenchError
        No variant works here.
    """
    return select_variant()


def one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
