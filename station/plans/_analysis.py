"""From stored measurements to positions: shared by the plans' ``analyse`` functions."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from station.plans import CaptureResult, PlanError
from station.vision import apply_homography, series_homography

FloatArray = npt.NDArray[np.float64]


def measured(captures: Sequence[CaptureResult]) -> list[CaptureResult]:
    """The captures whose measurement succeeded."""
    return [c for c in captures if c.measurement is not None and c.measurement.get("ok")]


def series_positions_mm(
    captures: Sequence[CaptureResult],
    groove_width_mm: float,
    *,
    relative_to_px: tuple[float, float] | None = None,
) -> FloatArray:
    """Each capture's crossing (mm, artifact axes) through one homography fitted over all of them (series
    calibration: per-image scale noise would otherwise dominate), relative to the artifact point seen at
    image pixel ``relative_to_px`` (default the image origin, as ``center_mm``)."""
    if len(captures) < 1:
        raise PlanError("no measured captures to analyse")
    ms = [c.measurement for c in captures if c.measurement is not None]
    centers = np.array([m["center_px"] for m in ms], dtype=np.float64).reshape(-1, 2)
    corners = [np.asarray(m["corners_px"], np.float64) for m in ms]
    H = series_homography(corners, groove_width_mm)
    ref = np.array([relative_to_px or (0.0, 0.0)], dtype=np.float64)
    return apply_homography(H, centers) - apply_homography(H, ref)[0]


def principal_point(
    captures: Sequence[CaptureResult], camera_matrix: Sequence[Sequence[float]] | None
) -> tuple[float, float]:
    """The image of the optical axis: the camera model's (cx, cy), else the image centre."""
    if camera_matrix is not None:
        return float(camera_matrix[0][2]), float(camera_matrix[1][2])
    sizes = {(c.width, c.height) for c in captures if c.width and c.height}
    if len(sizes) != 1:
        raise PlanError(
            f"captures of one test have different image sizes {sorted(sizes)}; set a camera model"
        )
    w, h = sizes.pop()
    return (w - 1) / 2.0, (h - 1) / 2.0


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
