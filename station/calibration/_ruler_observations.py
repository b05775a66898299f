"""A ruler's frames as the identification reads them: where along the ruler the camera looked, absolutely.

A :class:`RulerObservation` is one frame of a ruler (``station.vision.measure_ruler`` with the camera
model): the encoder readings, the ruler's coordinates ``(s, t)`` of the point under the reference pixel
(the principal point), the image scale there (``diagnostics.px_per_mm``: the graduations' pitch in
pixels over their calibrated pitch) and the distance sensor's reading when its beam falls on the ruler.
Unlike a crossing, whose position is known only relative to itself, ``s`` is an absolute length along a
calibrated scale: two frames far apart give the arm's displacement between them, and the scale gives
the camera's magnification. :func:`ruler_arrays` stacks them for the vectorised model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.calibration._observations import CalibrationError, FloatArray, IntArray, ObservationKind
from station.kinematics import JOINTS


@dataclass(frozen=True)
class RulerObservation:
    """One frame of a ruler.

    Attributes
    ----------
    joints_deg
        The six encoder readings at the capture (deg).
    position_mm, offset_mm
        The ruler's ``s`` and ``t`` of the point under ``reference_px`` (``measure_ruler``'s
        ``position_mm`` and ``offset_mm``), mm.
    reference_px
        The pixel they refer to: the principal point when measured with the camera model.
    px_per_mm
        The image scale at the reference pixel (``diagnostics.px_per_mm``), px/mm; None to leave the
        frame's scale out.
    z_mm
        The distance sensor's reading (mm, along its beam to the ruler's top surface); None when the
        beam does not fall on the ruler.
    configuration
        A posture reached by a planned move (ids shared with the crossings' observations: one posture,
        one id).
    ruler
        Which ruler (an id of ``CalibrationSetup.rulers``).
    kind
        ``"pose"`` or ``"inview"`` (a small motion from the configuration).
    """

    joints_deg: tuple[float, float, float, float, float, float]
    position_mm: float
    offset_mm: float
    reference_px: tuple[float, float]
    px_per_mm: float | None
    z_mm: float | None
    configuration: int
    ruler: int
    kind: ObservationKind = "pose"

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "joints_deg", tuple(float(v) for v in self.joints_deg))
            object.__setattr__(self, "reference_px", tuple(float(v) for v in self.reference_px))
            for name in ("position_mm", "offset_mm"):
                object.__setattr__(self, name, float(getattr(self, name)))
            for name in ("px_per_mm", "z_mm"):
                if getattr(self, name) is not None:
                    object.__setattr__(self, name, float(getattr(self, name)))
        except (TypeError, ValueError) as exc:
            raise CalibrationError(f"a ruler observation's values must be numbers: {exc}") from exc
        if len(self.joints_deg) != JOINTS or not all(math.isfinite(v) for v in self.joints_deg):
            raise CalibrationError(
                f"joints_deg must be {JOINTS} finite angles (deg), got {self.joints_deg!r}"
            )
        if not (math.isfinite(self.position_mm) and math.isfinite(self.offset_mm)):
            raise CalibrationError(
                f"position_mm and offset_mm must be finite, got {self.position_mm!r}, {self.offset_mm!r}"
            )
        if len(self.reference_px) != 2 or not all(math.isfinite(v) for v in self.reference_px):
            raise CalibrationError(
                f"reference_px must be 2 finite pixel coordinates, got {self.reference_px!r}"
            )
        for name in ("px_per_mm", "z_mm"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise CalibrationError(f"{name} must be a positive number or None, got {value!r}")
        if self.kind not in ("pose", "inview"):
            raise CalibrationError(f"kind must be 'pose' or 'inview', got {self.kind!r}")


@dataclass(frozen=True)
class RulerArrays:
    """Ruler observations stacked for the vectorised model (R frames)."""

    joints_deg: FloatArray  # (R, 6)
    st_mm: FloatArray  # (R, 2): position_mm, offset_mm
    reference_px: FloatArray  # (R, 2)
    scale: FloatArray  # (R,) px/mm, NaN where left out
    has_scale: npt.NDArray[np.bool_]  # (R,)
    z_mm: FloatArray  # (R,), NaN where there is no reading
    has_z: npt.NDArray[np.bool_]  # (R,)
    configuration: IntArray  # (R,)
    ruler_index: IntArray  # (R,), index into the model's rulers
    is_pose: npt.NDArray[np.bool_]  # (R,)

    def __len__(self) -> int:
        return int(self.joints_deg.shape[0])

    @property
    def residual_count(self) -> int:
        """Residuals these frames add: ``s`` and ``t`` each, the scale and the reading where present."""
        return 2 * len(self) + int(self.has_scale.sum()) + int(self.has_z.sum())


def ruler_arrays(observations: Sequence[RulerObservation], rulers: Sequence[int]) -> RulerArrays:
    """Stack ``observations``; ``rulers`` (sorted ids) maps each ruler id to its index."""
    index = {k: i for i, k in enumerate(rulers)}
    unknown = sorted({o.ruler for o in observations} - set(index))
    if unknown:
        raise CalibrationError(
            f"ruler observations see rulers {unknown} that the setup does not list; add their taught"
            " placements to CalibrationSetup.rulers"
        )
    scale = np.array([np.nan if o.px_per_mm is None else o.px_per_mm for o in observations], dtype=float)
    z = np.array([np.nan if o.z_mm is None else o.z_mm for o in observations], dtype=float)
    return RulerArrays(
        joints_deg=np.array([o.joints_deg for o in observations], dtype=float).reshape(-1, JOINTS),
        st_mm=np.array([(o.position_mm, o.offset_mm) for o in observations], dtype=float).reshape(-1, 2),
        reference_px=np.array([o.reference_px for o in observations], dtype=float).reshape(-1, 2),
        scale=scale,
        has_scale=np.isfinite(scale),
        z_mm=z,
        has_z=np.isfinite(z),
        configuration=np.array([o.configuration for o in observations], dtype=np.int64),
        ruler_index=np.array([index[o.ruler] for o in observations], dtype=np.int64),
        is_pose=np.array([o.kind == "pose" for o in observations], dtype=bool),
    )


__all__ = ["RulerArrays", "RulerObservation", "ruler_arrays"]
