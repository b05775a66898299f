"""How a ``validation`` session's results are shown: the terminal's summary and the CSV's rows (one per
position)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from station.plans._present import flat, um


def summary(results: Mapping[str, Any]) -> str:
    width = results.get("groove_width_mm")
    if results.get("artifact") == "ruler":
        return (
            f"  ruler on the table: raw (rigid) error mean {um(results['mean_um'])}, max "
            f"{um(results['max_um'])}; parallelogram mean {um(results.get('parallelogram_mean_um'))}, "
            f"max {um(results.get('parallelogram_max_um'))}\n"
            f"  scale {results['scale']:.6f} (the micrometers against the ruler's pitch); "
            f"{results.get('n_positions')} positions" + (" (partial)" if results.get("partial") else "")
        )
    return (
        f"  raw (rigid) error mean {um(results['mean_um'])}, max {um(results['max_um'])}; "
        f"parallelogram mean {um(results.get('parallelogram_mean_um'))}, "
        f"max {um(results.get('parallelogram_max_um'))}\n"
        f"  scale {results['scale']:.6f}: groove width {um(width, 'mm')} "
        f"(u {um(results.get('groove_width_u_mm'), 'mm')}); {results.get('n_positions')} positions"
        + (" (partial)" if results.get("partial") else "")
    )


def rows(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    return [flat(p) for p in results.get("positions", [])]
