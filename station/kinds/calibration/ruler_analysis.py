"""The calibration's analysis of its ruler frames (issue 22, item 5): from the session's captures of the
cell's rulers to the identification's :class:`~station.calibration.RulerObservation` s, and from its result
to the session's figures.

* Each ruler frame measured (``measure_ruler`` under the reference pixel: the principal point, else the
  image's centre, ``station.plans._ruler``) is one observation: its joints, the absolute position along
  the ruler and the offset across it, the image scale there (``diagnostics.px_per_mm``) and the distance
  sensor's reading when the beam, by the nominal model, falls on the ruler's glass (a reading beside it
  is of something else: left out of the frame, the frame kept).
* Held out of the fit: a share of each ruler's frames (as of each placement's configurations), whose
  pairs far apart give ``absolute_error_um``.
* ``magnification``: the camera's image scale at the capture plane as the rulers' certified pitch gives
  it (px/mm, its standard uncertainty and 95 % interval, against the nominal), and the sensor mount's
  offset along the optical axis; the ``magnification_groove_width`` gate compares it with the groove
  widths the crossings measured (``station.calibration.magnification_check``).
* ``scale_calibration``: the grooves' mean width at that magnification, with its standard uncertainty:
  the station's scale calibration from the rulers (``station.scale_calibration``, ``"source": "ruler"``),
  which the runner writes only when the session passed every ``fail`` gate.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from station.calibration import (
    CalibrationError,
    CalibrationResult,
    RulerObservation,
    RulerPlacement,
    magnification_check,
)
from station.kinds.calibration.ruler_plan import ruler_frame
from station.plans import CaptureResult
from station.plans._ruler import is_ruler

if TYPE_CHECKING:
    from station.kinds.calibration.params import CalibrationCell

GLASS_MARGIN_MM = 2.0
"""A sensor reading is kept only where the nominal beam meets the glass this far inside its edges."""


def ruler_placements(cell: CalibrationCell) -> dict[int, RulerPlacement]:
    """Each ruler's taught placement, by its index in the cell."""
    return {k: RulerPlacement(r.origin_mm, r.direction, r.normal) for k, r in enumerate(cell.rulers)}


def _beam_on_glass(cell: CalibrationCell, ruler: int, joints: Sequence[float]) -> bool:
    """Whether the sensor's beam, by the nominal model, meets ruler ``ruler``'s glass (with a margin)."""
    if cell.sensor_mount is None or not 0 <= ruler < len(cell.rulers):
        return False
    r = cell.rulers[ruler]
    head = cell.kinematics.forward(joints) @ cell.sensor_mount
    F = ruler_frame(r.origin_mm, r.direction, r.normal)
    n, o, d = F[:3, 2], head[:3, 3], head[:3, 2]
    along = float(n @ d)
    if along <= 1e-9:
        return False
    distance = float(n @ (F[:3, 3] - o)) / along
    s, t, _ = F[:3, :3].T @ (o + distance * d - F[:3, 3])
    inside_s = -GLASS_MARGIN_MM <= s <= r.length_mm + GLASS_MARGIN_MM
    return distance > 0 and inside_s and abs(t) <= r.glass_width_mm / 2.0 - GLASS_MARGIN_MM


def ruler_observations_from(
    captures: Sequence[CaptureResult], cell: CalibrationCell, reference_px: tuple[float, float]
) -> tuple[list[RulerObservation], list[dict[str, Any]]]:
    """The session's measured ruler frames as observations, and why each other ruler frame is left out."""
    out: list[RulerObservation] = []
    left: list[dict[str, Any]] = []
    for c in captures:
        if not is_ruler(c.meta) or c.meta.get("kind") != "pose":
            continue
        m = c.measurement
        why = None
        if m is None or not m.get("ok"):
            why = (m or {}).get("error") or "not measured"
        elif "joints_deg" not in c.meta:
            why = "no joint reading"
        if why is not None:
            left.append({"capture_id": c.capture_id, "kind": "ruler", "reason": why})
            continue
        assert m is not None
        joints = tuple(float(a) for a in c.meta["joints_deg"])
        ruler = int(c.meta["ruler"])
        scale = (m.get("diagnostics") or {}).get("px_per_mm")
        z = c.z_mm if c.z_mm is not None and _beam_on_glass(cell, ruler, joints) else None
        try:
            out.append(
                RulerObservation(
                    joints_deg=joints,  # type: ignore[arg-type]
                    position_mm=float(m["position_mm"]),
                    offset_mm=float(m["offset_mm"]),
                    reference_px=reference_px,
                    px_per_mm=None if scale is None else float(scale),
                    z_mm=z,
                    configuration=int(c.meta["configuration"]),
                    ruler=ruler,
                )
            )
        except CalibrationError as exc:
            left.append({"capture_id": c.capture_id, "kind": "ruler", "reason": str(exc)})
    return out, left


def ruler_holdout(observations: Sequence[RulerObservation], fraction: float, seed: int) -> list[int]:
    """Ruler frames held out of the fit: ``fraction`` of each ruler's (at least two where it has four or
    more, so that each ruler gives held-out pairs; two always kept in the fit), drawn with ``seed``."""
    if fraction <= 0:
        return []
    rng = np.random.default_rng([0x2A1, seed])
    held: list[int] = []
    by_ruler: dict[int, set[int]] = {}
    for o in observations:
        by_ruler.setdefault(o.ruler, set()).add(o.configuration)
    for r in sorted(by_ruler):
        configs = sorted(by_ruler[r])
        n = round(fraction * len(configs))
        if len(configs) >= 4:
            n = max(n, 2)
        n = min(n, len(configs) - 2)
        if n > 0:
            held += [int(c) for c in rng.choice(configs, size=n, replace=False)]
    return sorted(held)


def groove_widths_px(captures: Sequence[CaptureResult]) -> list[float]:
    """Every groove width (px) the session's crossing captures measured at the capture plane (its pose,
    in-view and return captures, ``diagnostics.groove_width_px``: not the alignment's, taken before
    focusing)."""
    out: list[float] = []
    for c in captures:
        m = c.measurement
        if is_ruler(c.meta) or c.meta.get("kind") not in ("pose", "inview", "return"):
            continue
        widths = (
            (m.get("diagnostics") or {}).get("groove_width_px") if m is not None and m.get("ok") else None
        )
        if widths:
            out += [float(v) for v in widths]
    return out


def ruler_results(
    result: CalibrationResult, observations: Sequence[RulerObservation], captures: Sequence[CaptureResult]
) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """The session's ruler figures (``absolute_error_um``, ``magnification``, the frames) and the
    magnification gate's check (None without an identified magnification or groove widths)."""
    cv = result.cross_validation
    out: dict[str, Any] = {
        "absolute_error_um": {k: cv.absolute_error_um.get(k) for k in ("before", "after", "floor")},
        "absolute_pairs": cv.absolute_pairs,
        "ruler_frames": len(observations),
        "rulers": sorted({o.ruler for o in observations}),
        "magnification": None,
    }
    mag = result.magnification
    if mag is None:
        return out, None
    sensor_z = result.parameter("sensor_z") if "sensor_z" in {p.name for p in result.parameters} else None
    out["magnification"] = {
        "px_per_mm": mag.px_per_mm,
        "sigma": mag.sigma,
        "interval": None if mag.interval is None else list(mag.interval),
        "nominal_px_per_mm": mag.nominal_px_per_mm,
        "relative_to_nominal": mag.relative_to_nominal,
        "sensor_z_mm": mag.sensor_z_mm,
        "sensor_z_sigma_mm": None if sensor_z is None else sensor_z.sigma,
        "source": mag.source,
    }
    widths = groove_widths_px(captures)
    if not widths:
        return out, None
    check = magnification_check(mag.px_per_mm, widths, px_per_mm_sigma=mag.sigma or 0.0)
    # the station's scale calibration from the rulers (written only when every fail gate passed)
    out["scale_calibration"] = {
        "groove_width_mm": check.implied_width_mm,
        "u_mm": check.width_u_mm,
        "source": "ruler",
    }
    return out, check.to_json()


__all__ = [
    "groove_widths_px",
    "ruler_holdout",
    "ruler_observations_from",
    "ruler_placements",
    "ruler_results",
]
