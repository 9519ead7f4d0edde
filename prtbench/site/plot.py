"""The interactive Pareto plot of one protocol panel (plotly figure JSON; plotly.js draws it).

One plot per panel (one reference and one view set, :mod:`.panels`): masked PSNR (clipped
at the reference noise ceiling) against frame time, one marker per configuration -- colour by
method, symbol by light class (relight, family, fixed; a legend group says which), filled on
the front and hollow when dominated -- with the 95 % interval of its error as an error bar,
the front as a step line and the noise ceiling as a grey band. Each marker carries its
configuration's id (``customdata``), which the page uses to open its images on click.
"""

from __future__ import annotations

import json
import math

from prtbench.api.method import METHODS
from prtbench.site.panels import fmt

#: Marker symbol of each light class (docs/PROTOCOL.md); a class not listed (``unknown``
#: for rows stored before the protocol, or mixed classes) gets :data:`OTHER_SYMBOL`.
CLASS_SYMBOLS = {"relight": "circle", "family": "diamond", "fixed": "square"}
OTHER_SYMBOL = "x"
#: Legend group of the light-class key (symbols only, no data).
_CLASS_GROUP = "light class"


def class_symbol(light_class: str) -> str:
    return CLASS_SYMBOLS.get(light_class, OTHER_SYMBOL)


def _colour(method: str) -> str:
    """A colour per method, fixed by its place among the registered methods."""
    from plotly.colors import qualitative

    names = METHODS.names()
    index = names.index(method) if method in names else len(names) + sum(map(ord, method))
    colours = qualitative.D3
    return colours[index % len(colours)]


def placed(configurations) -> list:
    """The configurations a plot shows: a Pareto point with a finite cost."""
    return [c for c in configurations if c.point.dominated is not None]


def _bars(members) -> dict:
    """Asymmetric error bars from each point's 95 % interval (none where it is unknown)."""
    above, below = [], []
    for c in members:
        p = c.point
        known = math.isfinite(p.error_lo) and math.isfinite(p.error_hi)
        above.append(max(p.error_hi - p.error, 0.0) if known else 0.0)
        below.append(max(p.error - p.error_lo, 0.0) if known else 0.0)
    return {"type": "data", "symmetric": False, "array": above, "arrayminus": below,
            "thickness": 1, "width": 3}


def figure(configurations, *, title: str) -> dict:
    """Plotly figure (``{"data", "layout"}``, plain JSON) of one panel's configurations."""
    import plotly.graph_objects as go

    shown = placed(configurations)
    fig = go.Figure()
    for method in sorted({c.method for c in shown}):
        colour = _colour(method)
        for front in (True, False):
            members = [c for c in shown if c.method == method and (not c.point.dominated) == front]
            if not members:
                continue
            symbols = [class_symbol(c.point.light_class) + ("" if front else "-open")
                       for c in members]
            fig.add_trace(go.Scatter(
                x=[c.point.cost for c in members], y=[c.point.error for c in members],
                mode="markers", name=method + ("" if front else " (dominated)"),
                legendgroup=method, customdata=[c.id for c in members],
                hovertext=[_hover(c) for c in members], hoverinfo="text",
                error_y={**_bars(members), "color": colour},
                marker={"symbol": symbols, "color": colour, "size": 11 if front else 10,
                        "line": {"width": 1 if front else 2, "color": "black" if front else colour}}))
    # The light-class key: legend entries only (no coordinates, so nothing is drawn).
    for light_class in sorted({c.point.light_class for c in shown}):
        fig.add_trace(go.Scatter(
            x=[None], y=[None], mode="markers", name=light_class, hoverinfo="skip",
            legendgroup=_CLASS_GROUP, legendgrouptitle={"text": _CLASS_GROUP},
            marker={"symbol": class_symbol(light_class), "color": "grey", "size": 10}))
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
    clipped = " (clipped)" if p.clipped else ""
    standing = {"yes": "on the front", "tie": "on the front, tie: within the intervals of "
                + "; ".join(c.ties), "": "dominated"}[c.front]
    return (f"<b>{c.method}</b> {c.description}<br>light class {p.light_class}, split {p.split}"
            f"<br>masked PSNR {c.error_text}{clipped}<br>masked FLIP {fmt(c.flip)}"
            f"<br>frame {fmt(p.cost)} ms<br>{standing}; click: images")
