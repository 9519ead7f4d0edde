"""The interactive Pareto plot of a scene page (plotly figure JSON; plotly.js draws it).

One plot per panel (material variant and resolution, as :mod:`prtbench.tradeoff.pareto`
compares only those): masked PSNR (clipped at the reference noise ceiling) against frame
time, one marker per stored configuration, filled on the front and hollow when dominated, the
front as a step line and the noise ceiling as a grey band. Each marker carries its
configuration's id (``customdata``), which the page uses to open its images on click.
"""

from __future__ import annotations

import json

from prtbench.api.method import METHODS

#: Marker symbols by a method's place among the registered methods (matches the PNG plots'
#: idea of one shape and colour per method).
_SYMBOLS = ("circle", "square", "triangle-up", "triangle-down", "diamond", "cross", "x",
            "star", "hexagon", "triangle-left", "triangle-right", "pentagon")


def _style(method: str) -> tuple[str, str]:
    from plotly.colors import qualitative

    names = METHODS.names()
    index = names.index(method) if method in names else len(names) + sum(map(ord, method))
    colours = qualitative.D3
    return _SYMBOLS[index % len(_SYMBOLS)], colours[index % len(colours)]


def placed(configurations) -> list:
    """The configurations a plot shows: a Pareto point with a finite cost."""
    return [c for c in configurations if c.point is not None and c.point.dominated is not None]


def figure(configurations, *, title: str) -> dict:
    """Plotly figure (``{"data", "layout"}``, plain JSON) of one panel's configurations."""
    import plotly.graph_objects as go

    shown = placed(configurations)
    fig = go.Figure()
    for method in sorted({c.method for c in shown}):
        symbol, colour = _style(method)
        for front in (True, False):
            members = [c for c in shown if c.method == method and (not c.point.dominated) == front]
            if not members:
                continue
            fig.add_trace(go.Scatter(
                x=[c.point.cost for c in members], y=[c.point.error for c in members],
                mode="markers", name=method + ("" if front else " (dominated)"),
                legendgroup=method,
                customdata=[c.id for c in members],
                hovertext=[_hover(c) for c in members], hoverinfo="text",
                marker={"symbol": symbol if front else f"{symbol}-open", "color": colour,
                        "size": 11 if front else 10,
                        "line": {"width": 1 if front else 2, "color": "black" if front else colour}}))
    front = sorted((c for c in shown if not c.point.dominated), key=lambda c: c.point.cost)
    if front:
        fig.add_trace(go.Scatter(x=[c.point.cost for c in front], y=[c.point.error for c in front],
                                 mode="lines", line={"shape": "hv", "color": "black", "width": 1.5},
                                 name="Pareto front", hoverinfo="skip"))
    ceilings = [c.point.ceiling_db for c in shown if c.point.ceiling_db is not None]
    if ceilings:
        fig.add_hrect(y0=min(ceilings) - 0.15, y1=max(ceilings) + 0.15, fillcolor="grey",
                      opacity=0.3, line_width=0, layer="below")
    costs = [c.point.cost for c in shown]
    log = bool(costs) and min(costs) > 0 and max(costs) / min(costs) > 20
    fig.update_layout(
        title={"text": title, "font": {"size": 13}}, height=430, margin={"l": 60, "r": 20, "t": 50, "b": 50},
        xaxis={"title": {"text": "frame time (ms, median; better ←)"}, "type": "log" if log else "linear"},
        yaxis={"title": {"text": "masked PSNR (dB, clipped at the noise ceiling; better ↑)"}},
        hovermode="closest", template="plotly_white", legend={"font": {"size": 10}})
    return json.loads(fig.to_json())


def _hover(c) -> str:
    p = c.point
    flip = "n/a" if c.flip is None else f"{c.flip:.4g}"
    clipped = " (clipped)" if p.clipped else ""
    return (f"<b>{c.method}</b> {c.description}<br>masked PSNR {p.error:.4g} dB{clipped}"
            f"<br>masked FLIP {flip}<br>frame {p.cost:.4g} ms<br>"
            f"{'on the front' if not p.dominated else 'dominated'}; click: images")

