"""How a ``repeatability`` session's results are shown: the terminal's summary (RP per test) and the
CSV's rows (one per cycle)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def summary(results: Mapping[str, Any]) -> str:
    lines = [f"  RP (mm), {results['n_cycles']} cycles planned per test:"]
    for test, e in results["tests"].items():
        n = e.get("n_cycles")
        count = f"N {n}" + (f" of {e.get('planned_cycles')}, partial" if e.get("partial") else "")
        if "rp_mm" in e:
            lo, hi = e["rp_ci95_mm"]
            lines.append(f"    {test:>4}  RP {e['rp_mm']:.5f}  (95 % {lo:.5f}-{hi:.5f})  {count}")
        else:
            lines.append(f"    {test:>4}  {e.get('error')}  {count if n is not None else ''}".rstrip())
    return "\n".join(lines)


def rows(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    out = []
    for test, body in (results.get("tests") or {}).items():
        points = body.get("points_mm") or body.get("points") or []
        cycles = body.get("cycles") or list(range(len(points)))
        for cycle, point in zip(cycles, points, strict=False):
            out.append(
                {"test": test, "cycle": cycle, **{f"{a}_mm": v for a, v in zip("xyz", point, strict=False)}}
            )
    return out
