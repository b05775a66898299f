"""How a ``calibration`` session's results are shown: the terminal's summary (the relative error before
and after, what was identified) and the CSV's rows (one per model parameter)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def summary(results: Mapping[str, Any]) -> str:
    rel = results["relative_error_um"]

    def um(v: Any) -> str:
        return "-" if v is None else f"{v:.1f} um"

    rulers = ""
    absolute, mag = results.get("absolute_error_um"), results.get("magnification")
    if absolute is not None:
        rulers = (
            f"  absolute error (along the rulers): before {um(absolute.get('before'))},"
            f" after {um(absolute.get('after'))}, floor {um(absolute.get('floor'))}\n"
        )
    if mag is not None:
        rulers += (
            f"  magnification {mag['px_per_mm']:.4f} px/mm from the rulers"
            f" ({mag['relative_to_nominal'] * 100:+.3f} % from nominal)\n"
        )
    return rulers + (
        f"  relative error (held-out configurations): before {um(rel.get('before'))},"
        f" after {um(rel.get('after'))}, floor {um(rel.get('floor'))}\n"
        f"  {results['identified_count']} parameters identified from {results['observations']} captures"
        f" of {results['configurations']} configurations;"
        f" condition number {results['condition_number']:.3g};"
        f" not identifiable on this arm: {', '.join(results['unidentifiable'])}"
    )


def rows(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    return [_parameter_row(p) for p in results.get("parameters") or [] if isinstance(p, dict)]


def _parameter_row(p: Mapping[str, Any]) -> dict[str, Any]:
    """One identified (or fixed) parameter of a calibration: its 95 % interval as two columns."""
    interval = p.get("interval") or [None, None]
    return {
        "name": p.get("name"),
        "unit": p.get("unit"),
        "nominal": p.get("nominal"),
        "estimate": p.get("estimate"),
        "interval_low": interval[0],
        "interval_high": interval[1],
        "sigma": p.get("sigma"),
        "identified": p.get("identified"),
        "structural": p.get("structural"),
    }
