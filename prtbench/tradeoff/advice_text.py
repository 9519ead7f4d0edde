"""``prtbench advise``'s terminal report: analysis, pruning, search, timing, the best
candidates and the verified answer (:class:`prtbench.tradeoff.advise.Advice`)."""

from __future__ import annotations

from prtbench.tradeoff.advise import Advice
from prtbench.tradeoff.search import Evaluation, fmt


def format_advice(advice: Advice, *, top: int = 8) -> str:
    """The terminal report: analysis, pruning, search, the best candidates and the answer."""
    judge_names = list(dict.fromkeys(c.name for c in advice.constraints))
    lines = ["analysis: " + " ".join(f"{k}={v}" for k, v in advice.analysis.items()
                                     if not isinstance(v, (dict, list)))]
    if advice.pruned:
        width = max(len(p["method"]) for p in advice.pruned)
        lines.append("pruned:")
        lines += [f"  {p['method']:<{width}}  {p['why']}" for p in advice.pruned]
    lines.append(f"search: {advice.evaluated} cells evaluated for a grid of {advice.grid_size} "
                 f"(+1 verification run)")
    if advice.steps:
        lines.append("time: " + ", ".join(s.describe() for s in advice.steps)
                     + f"; total {advice.total_s:.1f} s")
    lines += [f"  {n}" for n in advice.notes]
    final = [e for e in advice.history if e.profile == advice.choice.profile and e.row]
    shown = judge_names + ([] if advice.cost_kind in judge_names else [advice.cost_kind])
    header = ["method", "config", *shown, "meets"]
    rows = []
    for e in sorted(final, key=Evaluation.key)[:top]:
        values = [e.values.get(name) for name in judge_names]
        values += [] if advice.cost_kind in judge_names else [e.cost]
        rows.append([e.candidate.method, e.candidate.label(), *map(fmt, values),
                     "yes" if e.feasible else "no"])
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    lines.append(f"best candidates at the {advice.choice.profile} profile:")
    lines += ["  " + "  ".join(str(v).ljust(w) for v, w in zip(r, widths)).rstrip()
              for r in [header, *rows]]
    c = advice.to_json()
    mem = c["memory_bytes"]
    lines.append(f"{'choice' if advice.met else 'closest (target not reached)'} (verified, stored): "
                 f"{c['method']} {advice.choice.candidate.label()}: "
                 + ", ".join(f"{k} {fmt(c['metrics'].get(k))}" for k in judge_names
                             if k in c["metrics"])
                 + f"; frame {fmt(c['frame_ms'])} ms, memory "
                 f"{fmt(mem / 2 ** 20 if mem is not None else None)} MiB, precompute "
                 f"{fmt(c['precompute_s'])} s, {advice.cost_kind} {fmt(advice.choice.cost)}")
    if advice.runner_up is not None:
        lines.append(f"runner-up: {advice.runner_up.candidate.method} "
                     f"{advice.runner_up.candidate.label()} ({advice.cost_kind} "
                     f"{fmt(advice.runner_up.cost)})")
    if not advice.met:
        lines.append(f"needed: {advice.hint}")
    return "\n".join(lines)
