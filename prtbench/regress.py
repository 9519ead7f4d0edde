"""Golden-metric regression (DESIGN.md §13).

Every registered method runs in the ``smoke`` profile on its regression case (by default
``plants`` diffuse under ``sky``, one view) and its metrics against the path reference are
compared with ``tests/baselines/metrics.json``, which stores each value with an explicit
tolerance. Only ``prtbench regress --update`` rewrites the file; a method missing from the
baselines is a failure, not a silent pass.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .cache import atomic_path
from .errors import InvalidInputError

DEFAULT_BASELINES = Path(__file__).resolve().parent.parent / "tests" / "baselines" / "metrics.json"
DEFAULT_CASE = {"scene": "plants", "variant": "diffuse", "light": "sky"}
#: Absolute tolerances per metric: wide enough for Monte-Carlo and rasteriser differences
#: between machines (llvmpipe vs NVIDIA, llvm vs scalar Mitsuba), tight enough to catch a
#: broken shader, transfer or mapping (those move PSNR by several dB).
TOLERANCES = {"psnr_masked": 1.0, "ssim_masked": 0.03, "flip_masked": 0.02, "mae": 0.01}


def regression_case(method_cls) -> dict[str, Any]:
    """The scene/variant/light a method is regressed on."""
    return {**DEFAULT_CASE, **getattr(method_cls, "regression_case", {})}


def measure(method: str) -> tuple[dict[str, Any], dict[str, float]]:
    """Run ``method`` on its regression case in the smoke profile; (case, metrics)."""
    from .method import METHODS
    from .runner import RunRequest, run

    case = regression_case(METHODS.get(method))
    summary = run(RunRequest(method=method, scene=case["scene"], variant=case["variant"],
                             light=case["light"], profile="smoke", out_dir=None,
                             store_results=False, write_images=False),
                  progress=False, echo=False)
    return case, summary.mean_metrics()


def regress(*, update: bool = False, methods: Sequence[str] | None = None,
            baseline_path: Path | None = None) -> bool:
    """Compare (or with ``update``, rewrite) baselines; prints a report; True if all pass."""
    from .method import METHODS

    path = Path(baseline_path or DEFAULT_BASELINES)
    baselines = json.loads(path.read_text()) if path.exists() else {}
    names = list(methods) if methods else METHODS.names()
    for name in names:
        METHODS.check(name)
    ok = True
    for name in names:
        case, values = measure(name)
        if update:
            baselines[name] = {"case": case, "metrics": {
                m: {"value": round(float(values[m]), 5), "tolerance": tol}
                for m, tol in TOLERANCES.items()}}
            print(f"{name}: baseline updated " + ", ".join(f"{m}={values[m]:.4f}" for m in TOLERANCES))
            continue
        if name not in baselines:
            print(f"{name}: FAIL no baseline (run `prtbench regress --update --method {name}`)")
            ok = False
            continue
        entry = baselines[name]
        if entry.get("case") != case:
            raise InvalidInputError(f"baseline of '{name}' was recorded on {entry.get('case')}, "
                                    f"but the method's regression case is {case}; update it")
        for metric, spec in entry["metrics"].items():
            got, want, tol = float(values[metric]), float(spec["value"]), float(spec["tolerance"])
            passed = abs(got - want) <= tol
            ok &= passed
            print(f"{name}: {metric} = {got:.4f} (baseline {want:.4f} ± {tol}) "
                  f"{'ok' if passed else 'FAIL'}")
    if update:
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(baselines, indent=2, sort_keys=True) + "\n")
        print(f"wrote {path}", file=sys.stderr)
    return ok
