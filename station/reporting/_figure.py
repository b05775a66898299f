"""The report's figure machinery: figures drawn on ``matplotlib.figure.Figure`` objects with the Agg
canvas, never pyplot (nothing global leaks between reports or threads), the palette and the
magnification of small errors."""

from __future__ import annotations

import math
from dataclasses import dataclass

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

#: Colours (matplotlib's tab palette): table/fit, measured/error, RP, l-bar.
TABLE_C, ERROR_C, RP_C, LBAR_C, POINT_C = "#555555", "#d62728", "#d62728", "#7f7f7f", "#1f77b4"
MEAN_C, MAX_C = "#1f77b4", "#ff7f0e"
#: Calibration: nominal model (before), calibrated (after), the floor; structural parameters.
BEFORE_C, AFTER_C, FLOOR_C, STRUCT_C = "#d62728", "#2ca02c", "#7f7f7f", "#9467bd"


@dataclass(frozen=True)
class NamedFigure:
    """A figure with the file stem it is written under and its caption in the report."""

    name: str
    caption: str
    figure: Figure


def new_figure(width_in: float, height_in: float, *, layout: bool = True) -> Figure:
    fig = Figure(figsize=(width_in, height_in), layout="constrained" if layout else None)
    FigureCanvasAgg(fig)
    return fig


def nice_floor(x: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above ``x`` (x > 0)."""
    k = math.floor(math.log10(x))
    for m in (5.0, 2.0, 1.0):
        if m * 10.0**k <= x * (1 + 1e-9):
            return m * 10.0**k
    return 10.0**k  # pragma: no cover  (m = 1 always fits)


def magnification(span: float, max_error: float, *, fraction: float = 0.15) -> float:
    """A round factor drawing the largest error as about ``fraction`` of the pattern's span (>= 1)."""
    if max_error <= 0 or span <= 0 or not math.isfinite(max_error):
        return 1.0
    return max(1.0, nice_floor(fraction * span / max_error))


def fmt_magnification(mag: float) -> str:
    return f"{mag:,.0f}" if mag >= 1 else f"{mag:g}"
