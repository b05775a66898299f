"""From stored measurements to positions: shared by the plans' ``analyse`` functions."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from station.plans import CaptureResult, PlanError
from station.vision import series_centers_mm

FloatArray = npt.NDArray[np.float64]


def measured(captures: Sequence[CaptureResult]) -> list[CaptureResult]:
    """The captures whose measurement succeeded."""
    return [c for c in captures if c.measurement is not None and c.measurement.get("ok")]


def series_positions_mm(captures: Sequence[CaptureResult], groove_width_mm: float) -> FloatArray:
    """Each capture's crossing (mm, artifact axes, relative to the image origin) through one homography
    fitted over all of them (series calibration: per-image scale noise would otherwise dominate)."""
    if len(captures) < 1:
        raise PlanError("no measured captures to analyse")
    centers = [tuple(c.measurement["center_px"]) for c in captures if c.measurement is not None]
    corners = [
        np.asarray(c.measurement["corners_px"], np.float64) for c in captures if c.measurement is not None
    ]
    return series_centers_mm(centers, corners, groove_width_mm)


def group_mean(keys: Sequence[Any], values: FloatArray) -> tuple[list[Any], FloatArray]:
    """Mean of ``values`` rows per key, keys in first-seen order (averaging is analysis, not capture)."""
    order: list[Any] = []
    sums: dict[Any, list[FloatArray]] = {}
    for k, v in zip(keys, values, strict=True):
        if k not in sums:
            order.append(k)
            sums[k] = []
        sums[k].append(v)
    return order, np.array([np.mean(sums[k], axis=0) for k in order])


def failures(captures: Sequence[CaptureResult]) -> list[dict[str, Any]]:
    """The captures whose measurement failed, with the reason (reported with the results)."""
    out = []
    for c in captures:
        m = c.measurement
        if m is None or not m.get("ok"):
            out.append(
                {
                    "capture_id": c.capture_id,
                    "step_index": c.step_index,
                    "frame_index": c.frame_index,
                    "error": None if m is None else m.get("error"),
                    "code": None if m is None else m.get("code"),
                }
            )
    return out
