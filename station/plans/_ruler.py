"""Captures of a ruler: a plan marks them (``meta["artifact"] = "ruler"``), the runner measures them with
``station.vision.measure_ruler`` instead of the cross, with the session's camera model and bit depth.

The position is that of the ruler point under the **reference pixel**: the camera model's principal point,
or, without a model, the image's centre (a pinhole with the ruler's nominal focal length and no
distortion): there the pattern's fit is best determined, where a corner pixel would add the angle's
error times the distance to the corner (about 0.3 um on the offset at 4 mm). The identification takes
the same pixel (:func:`reference_px`). A plan may ask for a looser tilt prior
(``meta["ruler_max_tilt_deg"]``: a frame taken leaning).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from station.vision import MeasureParams, RulerParams

#: The capture metadata's key and value that mark a frame of a ruler.
ARTIFACT_KEY = "artifact"
RULER = "ruler"
#: The capture metadata's key for the tilt prior of a frame taken leaning (deg).
MAX_TILT_KEY = "ruler_max_tilt_deg"


def is_ruler(meta: Mapping[str, Any]) -> bool:
    """Whether a capture (its metadata) is a frame of a ruler."""
    return meta.get(ARTIFACT_KEY) == RULER


#: The capture metadata's value (under :data:`ARTIFACT_KEY`) of a frame that is no groove artifact's (a
#: camera calibration's view of its target): stored, never measured; its plan reads the image.
NOT_MEASURED = ("target",)


def measured(meta: Mapping[str, Any]) -> bool:
    """Whether the runner measures a capture (its metadata): every frame but one of a calibration target."""
    return meta.get(ARTIFACT_KEY) not in NOT_MEASURED


def ruler_params(measure: MeasureParams, **changes: Any) -> RulerParams:
    """The ruler's measurement parameters for a session measuring with ``measure``: its camera model and
    bit depth carried over, the ruler's own defaults otherwise (``changes`` override them)."""
    values: dict[str, Any] = {
        "camera_matrix": measure.camera_matrix,
        "dist_coeffs": measure.dist_coeffs,
        "bit_depth": measure.bit_depth,
        **changes,
    }
    return RulerParams.model_validate(values)


def reference_px(measure: MeasureParams, width: int, height: int) -> tuple[float, float]:
    """The pixel a ruler frame's position refers to: the principal point, else the image's centre."""
    if measure.camera_matrix is not None:
        return float(measure.camera_matrix[0][2]), float(measure.camera_matrix[1][2])
    return (width - 1) / 2.0, (height - 1) / 2.0


def capture_params(
    meta: Mapping[str, Any], measure: MeasureParams, shape: tuple[int, ...]
) -> MeasureParams | RulerParams:
    """What a capture (its metadata, its image's ``shape``) is measured with: the ruler's parameters for a
    frame of a ruler (see the module notes), else ``measure``."""
    if not is_ruler(meta):
        return measure
    changes: dict[str, Any] = {}
    if meta.get(MAX_TILT_KEY) is not None:
        changes["max_tilt_deg"] = float(meta[MAX_TILT_KEY])
    if measure.camera_matrix is None:
        cx, cy = reference_px(measure, int(shape[1]), int(shape[0]))
        focal = float(RulerParams.model_fields["focal_px"].default)
        changes["camera_matrix"] = [[focal, 0.0, cx], [0.0, focal, cy], [0.0, 0.0, 1.0]]
        changes["dist_coeffs"] = None
    return ruler_params(measure, **changes)


__all__ = [
    "ARTIFACT_KEY",
    "MAX_TILT_KEY",
    "NOT_MEASURED",
    "RULER",
    "capture_params",
    "is_ruler",
    "measured",
    "reference_px",
    "ruler_params",
]
