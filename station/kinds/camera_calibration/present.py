"""How a ``camera-calibration`` session's results are shown: the terminal's summary and the CSV's rows (one
per intrinsic)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

_NAMES = ("fx", "fy", "cx", "cy")


def _estimates(results: Mapping[str, Any]) -> list[tuple[str, Mapping[str, Any]]]:
    out = [(n, results[n]) for n in _NAMES if isinstance(results.get(n), Mapping)]
    out += [(n, e) for n, e in (results.get("distortion") or {}).items() if isinstance(e, Mapping)]
    return out


def summary(results: Mapping[str, Any]) -> str:
    lines = [
        f"  camera calibration: {'passed' if results.get('passed') else 'NOT passed'}, "
        f"{results.get('views')} of {results.get('views_taken')} views, "
        f"re-projection {float(results.get('rms_px', 0.0)):.3f} px, image {results.get('image_size')}"
    ]
    for name, e in _estimates(results):
        sigma = e.get("sigma")
        lines.append(f"  {name} = {e['value']:.6g}" + ("" if sigma is None else f" +/- {sigma:.2g}"))
    if results.get("camera_model_file"):
        lines.append(f"  camera model written to {results['camera_model_file']}")
    return "\n".join(lines)


def rows(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    return [{"name": n, "value": e["value"], "sigma": e.get("sigma")} for n, e in _estimates(results)]
