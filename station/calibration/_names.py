"""The calibration's parameter names, internal units and measurement sigmas (the model's vocabulary;
the model itself is ``_model``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from station.calibration._observations import CalibrationError
from station.kinematics import JOINTS

ANGLE_UNIT_DEG = math.degrees(1e-3)
"""Internal unit of angles: 1 mrad (so that 1 internal unit of an angle moves a 1 m lever by 1 mm)."""

DH_FIELDS = ("alpha", "a", "d", "theta")
TOOL_NAMES = ("tool_x", "tool_y", "tool_z", "tool_rx", "tool_ry", "tool_rz")
ARTIFACT_FIELDS = ("x", "y", "z", "rx", "ry")
RULER_FIELDS = ("x", "y", "z", "rx", "ry", "rz")
CAMERA_NAMES = ("px_per_mm", "sensor_z")
SCALE_UNIT = 0.1
"""Internal unit of ``px_per_mm``: 0.1 px/mm (0.1 % of the sim's 100 px/mm)."""
HAYATI_ROW = 2
"""DH row index (0-based) carrying ``beta2``: the link between the nominally parallel axes 2 and 3."""


def dh_names() -> list[str]:
    """The 24 DH parameter names in row order, then ``beta2``."""
    names: list[str] = []
    for i in range(1, JOINTS + 1):
        names += [f"alpha{i - 1}", f"a{i - 1}", f"d{i}", f"theta{i}_offset"]
    return [*names, f"beta{HAYATI_ROW}"]


def artifact_names(placement: int) -> list[str]:
    """The five parameter names of one artifact placement."""
    return [f"artifact{placement}_{f}" for f in ARTIFACT_FIELDS]


def ruler_names(ruler: int) -> list[str]:
    """The six parameter names of one ruler."""
    return [f"ruler{ruler}_{f}" for f in RULER_FIELDS]


@dataclass(frozen=True)
class Sigmas:
    """The measurement's standard deviations (mm) that weight the residuals.

    ``xy_mm``: the crossing's position in the image, at the focal plane (a pixel times the scale);
    ``z_mm``: the distance sensor's reading; ``ruler_mm``: a ruler frame's ``s`` and ``t`` under the
    reference pixel. All should include the arm's repeatability, which moves the camera between
    captures as much as the measurement's own noise does (a ruler's own noise is tens of nanometres).
    ``scale_rel``: a ruler frame's image scale, relative; the measurement's is a few ppm, the arm's
    repeatability along the optical axis (5 um in 68 mm: 7e-5) is most of it.
    """

    xy_mm: float = 0.005
    z_mm: float = 0.005
    ruler_mm: float = 0.005
    scale_rel: float = 1e-4

    def __post_init__(self) -> None:
        values = (self.xy_mm, self.z_mm, self.ruler_mm, self.scale_rel)
        if not all(math.isfinite(v) and v > 0 for v in values):
            raise CalibrationError(
                f"sigmas must be > 0, got xy_mm={self.xy_mm!r}, z_mm={self.z_mm!r},"
                f" ruler_mm={self.ruler_mm!r}, scale_rel={self.scale_rel!r}"
            )


__all__ = [
    "ANGLE_UNIT_DEG",
    "ARTIFACT_FIELDS",
    "CAMERA_NAMES",
    "DH_FIELDS",
    "HAYATI_ROW",
    "RULER_FIELDS",
    "SCALE_UNIT",
    "TOOL_NAMES",
    "Sigmas",
    "artifact_names",
    "dh_names",
    "ruler_names",
]
