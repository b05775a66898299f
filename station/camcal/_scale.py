"""The scale check: does the camera model, at the distance the station believes, see the groove as wide as
the artifact is?

A capture of the crossed-groove artifact, square to the camera at distance ``Z`` from the camera's centre,
shows each groove ``f w / Z`` px wide (``f`` the focal length in px along the width's direction, ``w`` the
groove's width): three things the station takes from elsewhere (the camera model, the distance from the
sensor's reading and mount or the working distance, the artifact's width from its drawing or the scale
calibration) against one it measures (``groove_width_px``, every measurement's diagnostics). A 1 % error
in the focal length or in the distance shows as a 1 % disagreement. The artifact's width is known to its
tolerance (+0/-0.002 in on 0.794 mm: up to 6.4 % narrow) unless a scale calibration measured it, so the
check compares the width the capture implies with the interval the width can be in, and reports how far
outside it falls (0 inside). A pre-flight fails beyond 0.2 %.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from station.camcal._errors import ScaleCheckError
from station.camera_model import CameraIntrinsics

__all__ = ["SCALE_CHECK_LIMIT", "ScaleCheck", "check_scale", "distance_from_sensor"]

FloatArray = npt.NDArray[np.float64]

SCALE_CHECK_LIMIT = 0.002
"""Largest relative disagreement a pre-flight accepts (issue 23: 0.2 %)."""


@dataclass(frozen=True)
class ScaleCheck:
    """The outcome of :func:`check_scale`.

    Attributes
    ----------
    expected_px : (float, float)
        Widths (horizontal groove, vertical groove) the model predicts for the nominal width, px.
    measured_px : (float, float)
        The capture's ``groove_width_px``.
    implied_width_mm : (float, float)
        The widths the model and distance make of the measured pixels, mm.
    width_interval_mm : (float, float)
        Where the artifact's true width can be, mm.
    disagreement : float
        Relative distance of the worse implied width from the interval (0 inside it; positive: the
        capture sees the groove wider than the model allows: the model's focal length too short, or the
        distance in use too long).
    u_rel : float
        Standard uncertainty of the implied widths (relative) from the focal length's, the distance's and
        the width measurement's.
    """

    expected_px: tuple[float, float]
    measured_px: tuple[float, float]
    implied_width_mm: tuple[float, float]
    width_interval_mm: tuple[float, float]
    disagreement: float
    u_rel: float

    def passes(self, limit: float = SCALE_CHECK_LIMIT) -> bool:
        """Whether the disagreement is within ``limit`` (relative)."""
        return abs(self.disagreement) <= limit

    def problem(self, limit: float = SCALE_CHECK_LIMIT) -> str | None:
        """None when it passes; else what disagrees and what to do."""
        if self.passes(limit):
            return None
        lo, hi = self.width_interval_mm
        seen = " and ".join(f"{w:.4f}" for w in self.implied_width_mm)
        direction = "wider" if self.disagreement > 0 else "narrower"
        return (
            f"scale check: the camera model at the distance in use makes the grooves {seen} mm wide, "
            f"{abs(self.disagreement):.2%} {direction} than the artifact can be ({lo:.4f}-{hi:.4f} mm; limit "
            f"{limit:.2%}): calibrate the camera (station run camera-calibration), teach the sensor mount "
            "(station teach sensor-mount) or check the working distance, and check the artifact's width "
            "(a scale calibration measures it)"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "expected_px": list(self.expected_px),
            "measured_px": list(self.measured_px),
            "implied_width_mm": list(self.implied_width_mm),
            "width_interval_mm": list(self.width_interval_mm),
            "disagreement": self.disagreement,
            "u_rel": self.u_rel,
        }


def distance_from_sensor(reading_mm: float, mount: npt.ArrayLike) -> float:
    """Distance (mm) from the camera's centre to a plane square to the optical axis, from the sensor.

    ``mount``: the sensor's 4x4 pose in the camera frame (its origin the reference point its readings
    start from, +z its beam; ``SensorMount.matrix()``); ``reading_mm``: its distance along the beam.
    """
    T = np.asarray(mount, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ScaleCheckError(f"the sensor mount must be a finite 4x4 transform, got shape {T.shape}")
    if not (math.isfinite(reading_mm) and reading_mm > 0):
        raise ScaleCheckError(f"the sensor reading must be a positive distance, got {reading_mm!r} mm")
    beam_z = float(T[2, 2])
    if beam_z < 0.5:
        raise ScaleCheckError(
            "the sensor's beam is more than 60 deg from the optical axis: no distance along it"
        )
    return float(T[2, 3]) + reading_mm * beam_z


def check_scale(
    intrinsics: CameraIntrinsics,
    *,
    distance_mm: float,
    groove_width_px: Sequence[float],
    groove_width_mm: float,
    width_tolerance_mm: tuple[float, float] = (-0.0508, 0.0),
    rotation_deg: float = 0.0,
    center_px: Sequence[float] | None = None,
    undistorted: bool = False,
    distance_u_mm: float = 0.0,
    width_u_px: float = 0.02,
) -> ScaleCheck:
    """Compare the groove widths a capture measured with what the camera model and distance predict.

    Parameters
    ----------
    intrinsics : CameraIntrinsics
        The camera model (its ``sigma`` enters the uncertainty).
    distance_mm : float
        From the camera's centre to the artifact's plane along the optical axis, mm: the working
        distance, or :func:`distance_from_sensor` of the capture's reading. The artifact is taken to be
        square to the optical axis (the reference pose, or after Align).
    groove_width_px : (float, float)
        The measurement's ``groove_width_px`` (horizontal groove, vertical groove).
    groove_width_mm : float
        The artifact's width: nominal (drawing) or the scale calibration's.
    width_tolerance_mm : (float, float)
        How far below and above ``groove_width_mm`` the true width may be, mm: the drawing's +0/-0.002 in
        by default; ``(-2u, 2u)`` for a scale calibration of standard uncertainty ``u``.
    rotation_deg : float
        The measurement's ``rotation_deg`` (the grooves' turn in the image).
    center_px : (float, float), optional
        Where the crossing is in the image (the distortion's local scale there); default: the principal
        point.
    undistorted : bool
        True when the measurement corrected the lens distortion with this model (``--camera-model``).
    distance_u_mm, width_u_px : float
        Standard uncertainties of the distance (mm) and of each measured width (px).

    Returns
    -------
    ScaleCheck
    """
    widths = [float(w) for w in groove_width_px]
    lo, hi = groove_width_mm + width_tolerance_mm[0], groove_width_mm + width_tolerance_mm[1]
    values = (
        distance_mm,
        groove_width_mm,
        *widths,
        *width_tolerance_mm,
        rotation_deg,
        distance_u_mm,
        width_u_px,
    )
    if len(widths) != 2 or not all(math.isfinite(v) for v in values):
        raise ScaleCheckError("the scale check needs two finite groove widths (px) and finite inputs")
    if not (distance_mm > 0 and groove_width_mm > 0 and min(widths) > 0 and 0 < lo <= hi):
        raise ScaleCheckError(
            f"distance {distance_mm} mm, width {groove_width_mm} mm (interval {lo}-{hi}) and groove widths "
            f"{widths} px must all be positive, with a tolerance whose lower end is below its upper"
        )
    if distance_u_mm < 0 or width_u_px < 0:
        raise ScaleCheckError("uncertainties must be >= 0")
    center = intrinsics.principal_point if center_px is None else (float(center_px[0]), float(center_px[1]))
    jac = np.eye(2) if undistorted else _distortion_jacobian(intrinsics, center)
    rho = math.radians(rotation_deg)
    # Image directions of the horizontal and the vertical groove (the measurement's rotation turns both).
    directions = [(math.cos(rho), math.sin(rho)), (-math.sin(rho), math.cos(rho))]
    fx, fy = intrinsics.fx, intrinsics.fy
    expected = []
    for dx, dy in directions:
        along = np.array([dx / fx, dy / fy])  # the groove's direction on the plane (normalised coordinates)
        along /= np.linalg.norm(along)
        across = np.array([-along[1], along[0]])
        a_img = jac @ (np.array([fx, fy]) * along)
        offset = jac @ (np.array([fx, fy]) * across * groove_width_mm / distance_mm)
        expected.append(
            abs(float(a_img[0] * offset[1] - a_img[1] * offset[0])) / float(np.linalg.norm(a_img))
        )
    implied = [groove_width_mm * m / e for m, e in zip(widths, expected, strict=True)]
    outside = [(w - hi) / hi if w > hi else (w - lo) / lo if w < lo else 0.0 for w in implied]
    disagreement = max(outside, key=abs)
    sigma = intrinsics.sigma
    f_rel = math.hypot(sigma.get("fx", 0.0) / fx, sigma.get("fy", 0.0) / fy) / math.sqrt(2.0)
    u_rel = math.sqrt(f_rel**2 + (distance_u_mm / distance_mm) ** 2 + (width_u_px / min(widths)) ** 2)
    return ScaleCheck(
        (expected[0], expected[1]),
        (widths[0], widths[1]),
        (implied[0], implied[1]),
        (lo, hi),
        disagreement,
        u_rel,
    )


def _distortion_jacobian(intrinsics: CameraIntrinsics, center_px: tuple[float, float]) -> FloatArray:
    """d(distorted px) / d(pinhole px) at the image point ``center_px`` (2x2), by central differences."""
    K, dist = intrinsics.camera_matrix, intrinsics.dist_coeffs
    ray = cv2.undistortPoints(np.array([[center_px]], dtype=np.float64), K, dist).reshape(2)
    h = 1e-4  # normalised units: 0.7 px at f = 6800 px
    pts = np.array([[ray[0] + h, ray[1]], [ray[0] - h, ray[1]], [ray[0], ray[1] + h], [ray[0], ray[1] - h]])
    proj, _ = cv2.projectPoints(np.column_stack([pts, np.ones(4)]), np.zeros(3), np.zeros(3), K, dist)
    p = proj.reshape(4, 2)
    d_dx, d_dy = (p[0] - p[1]) / (2 * h), (p[2] - p[3]) / (2 * h)
    pinhole = np.diag([K[0, 0], K[1, 1]])
    return np.asarray(np.column_stack([d_dx, d_dy]) @ np.linalg.inv(pinhole), dtype=np.float64)
