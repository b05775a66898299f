"""Does the magnification a calibration identified agree with the groove widths its crossings measured?

A calibration with rulers identifies the camera's image scale at the capture plane from the rulers'
calibrated pitch (``CalibrationResult.magnification``). Every capture of a crossing, at the same plane,
also measured the grooves' widths in pixels (``groove_width_px``, each measurement's diagnostics): over
the session's captures, their mean divided by the scale is the grooves' width in millimetres, which the
artifact's drawing bounds (1/32 in, +0/-0.002 in: up to 6.4 % narrow). Outside those bounds, beyond
``k`` standard uncertainties (the scale's, from its interval, and the widths' mean's), one of the three
is wrong: the rulers' description (their pitch), the artifact (another width), or the captures (not at
the capture plane); a gate must then fail the calibration.

``station.camcal.check_scale`` makes the same comparison for one capture against a camera model and a
distance; here it is the session's, against what the rulers measured, in the form the session gates
take (``{"name", "passed", "value", "limit", "severity", "message"}``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from station.calibration._observations import CalibrationError
from station.vision import NOMINAL_GROOVE_WIDTH_MM

CHECK_NAME = "magnification_groove_width"
DRAWING_TOLERANCE_MM = (-0.0508, 0.0)
"""The grooves' width below and above the drawing's 1/32 in: +0/-0.002 in."""


@dataclass(frozen=True)
class MagnificationCheck:
    """The verdict of :func:`magnification_check`.

    Attributes
    ----------
    passed
        The implied width lies in the artifact's interval, within ``k`` standard uncertainties.
    disagreement
        Relative distance of the implied width from the interval (0 inside it; positive: wider than the
        artifact can be, the scale too small).
    implied_width_mm, width_u_mm
        The grooves' mean width at the identified scale, and its standard uncertainty (mm).
    interval_mm
        Where the artifact's width can be (mm).
    captures
        How many widths went into the mean.
    message
        What agrees, or what disagrees and what to do.
    """

    passed: bool
    disagreement: float
    implied_width_mm: float
    width_u_mm: float
    interval_mm: tuple[float, float]
    captures: int
    message: str

    def to_json(self) -> dict[str, Any]:
        """The check in the session gates' form (``severity`` fail: a disagreement fails the gate)."""
        return {
            "name": CHECK_NAME,
            "passed": self.passed,
            "value": self.disagreement,
            "limit": list(self.interval_mm),
            "severity": "fail",
            "message": self.message,
        }


def magnification_check(
    px_per_mm: float,
    groove_widths_px: Sequence[float],
    *,
    px_per_mm_sigma: float = 0.0,
    width_mm: float = NOMINAL_GROOVE_WIDTH_MM,
    tolerance_mm: tuple[float, float] = DRAWING_TOLERANCE_MM,
    width_u_px: float = 0.02,
    k: float = 3.0,
) -> MagnificationCheck:
    """Compare the grooves' widths a session measured (px) with the magnification it identified.

    Parameters
    ----------
    px_per_mm, px_per_mm_sigma
        The identified scale at the capture plane and its standard uncertainty
        (``CalibrationResult.magnification``: ``px_per_mm``, ``sigma``), px/mm.
    groove_widths_px
        Every width the session's crossings measured at the capture plane (both grooves of each
        capture: ``groove_width_px``), px.
    width_mm, tolerance_mm
        The artifact's width (the drawing's, or a scale calibration's) and how far below and above it
        the true width may be (mm).
    width_u_px
        Standard uncertainty of one measured width (px).
    k
        Coverage: the implied width may lie this many standard uncertainties outside the interval.

    Raises
    ------
    CalibrationError
        No widths, or non-finite or non-positive inputs.
    """
    widths = np.asarray([float(w) for w in groove_widths_px], dtype=float)
    values = (px_per_mm, px_per_mm_sigma, width_mm, *tolerance_mm, width_u_px, k)
    if widths.size == 0:
        raise CalibrationError(
            "the magnification check needs the groove widths the session's captures measured"
        )
    if not (np.all(np.isfinite(widths)) and all(math.isfinite(v) for v in values)):
        raise CalibrationError("the magnification check's inputs must be finite numbers")
    lo, hi = width_mm + tolerance_mm[0], width_mm + tolerance_mm[1]
    if not (px_per_mm > 0 and np.all(widths > 0) and 0 < lo <= hi and px_per_mm_sigma >= 0 and k > 0):
        raise CalibrationError(
            f"scale {px_per_mm} px/mm, widths and interval {lo}-{hi} mm must be positive, the interval's"
            " lower end below its upper, the uncertainties >= 0"
        )
    mean_px = float(widths.mean())
    spread = float(widths.std(ddof=1)) if widths.size > 1 else width_u_px
    width = mean_px / px_per_mm
    u_rel = math.hypot(
        px_per_mm_sigma / px_per_mm, max(spread, width_u_px) / math.sqrt(widths.size) / mean_px
    )
    u = width * u_rel
    outside = (width - hi) / hi if width > hi + k * u else (width - lo) / lo if width < lo - k * u else 0.0
    if outside == 0.0:
        message = (
            f"the magnification the rulers measured, {px_per_mm:.4f} px/mm, makes the grooves {width:.4f} mm"
            f" wide (+/- {u:.4f}, {widths.size} widths): within the artifact's {lo:.4f}-{hi:.4f} mm"
        )
    else:
        side = "wider" if outside > 0 else "narrower"
        message = (
            f"the magnification the rulers measured, {px_per_mm:.4f} px/mm, makes the grooves {width:.4f} mm"
            f" wide (+/- {u:.4f}), {abs(outside):.2%} {side} than the artifact can be ({lo:.4f}-{hi:.4f} mm):"
            " check the rulers' description (their pitch and certificate), the artifact's width (a scale"
            " calibration measures it) and that the crossings were captured at the working distance, then"
            " run the calibration again"
        )
    return MagnificationCheck(
        passed=outside == 0.0,
        disagreement=outside,
        implied_width_mm=width,
        width_u_mm=u,
        interval_mm=(lo, hi),
        captures=int(widths.size),
        message=message,
    )


__all__ = ["CHECK_NAME", "DRAWING_TOLERANCE_MM", "MagnificationCheck", "magnification_check"]
