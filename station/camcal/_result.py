"""What a camera calibration found: the model, where its focal length came from, each view's diagnostics."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from station.camcal._heights import HeightScale
from station.camera_model import CameraIntrinsics

__all__ = ["AGREE_SIGMA", "FocalScale", "IntrinsicsCalibration", "ViewDiagnostics"]

AGREE_SIGMA = 3.0
"""Tilted views further than this many combined standard uncertainties from the heights are reported."""


@dataclass(frozen=True)
class ViewDiagnostics:
    """One view in the fit.

    ``corners``: corners used (``dropped``: left out as outliers); ``rms_px`` / ``max_px``: their
    re-projection error; ``coverage``: share of the frame inside their hull; ``tilt_deg``: the angle
    between the target's normal and the optical axis; ``distance_mm``: from the camera's centre to the
    target's plane along the optical axis; ``rvec`` / ``tvec_mm``: the target's pose in the camera;
    ``pose_only``: the view took no part in the intrinsics' fit, only its pose was found (a square view
    followed into the blur, for the heights).
    """

    index: int
    corners: int
    dropped: int
    rms_px: float
    max_px: float
    coverage: float
    tilt_deg: float
    distance_mm: float
    rvec: tuple[float, float, float]
    tvec_mm: tuple[float, float, float]
    pose_only: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "corners": self.corners,
            "dropped": self.dropped,
            "rms_px": self.rms_px,
            "max_px": self.max_px,
            "coverage": self.coverage,
            "tilt_deg": self.tilt_deg,
            "distance_mm": self.distance_mm,
            "rvec": list(self.rvec),
            "tvec_mm": list(self.tvec_mm),
            "pose_only": self.pose_only,
        }


@dataclass(frozen=True)
class FocalScale:
    """Where the focal length came from: the tilted views (Zhang's method) or the heights.

    ``tilted_fx_px`` / ``tilted_u_rel``: what the fit with every intrinsic free gave, with OpenCV's
    uncertainty; ``heights``: the scale from views square to the target at known heights (None without
    readings). With heights, the focal lengths are the fit's divided by ``heights.kappa`` (the aspect
    ratio stays the fit's) and the tilted views' only check them: the blur across tilted views biases
    them beyond what their uncertainty says whenever the depth of field is shallow (``TARGET.md``), and
    nothing in the views tells how shallow it is, so they are never averaged in.
    """

    tilted_fx_px: float
    tilted_u_rel: float
    heights: HeightScale | None

    @property
    def source(self) -> str:
        return "tilted views" if self.heights is None else "heights"

    @property
    def scale(self) -> float:
        """The fitted focal lengths were divided by this."""
        return 1.0 if self.heights is None else self.heights.kappa

    @property
    def u_rel(self) -> float:
        """The focal length's relative standard uncertainty."""
        return self.tilted_u_rel if self.heights is None else self.heights.u_rel

    @property
    def disagreement_sigma(self) -> float | None:
        """How far the tilted views' focal length is from the heights', in combined standard uncertainties."""
        if self.heights is None:
            return None
        return (self.heights.kappa - 1.0) / math.hypot(self.tilted_u_rel, self.heights.u_rel)

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "tilted_fx_px": self.tilted_fx_px,
            "tilted_u_rel": self.tilted_u_rel,
            "heights": None if self.heights is None else self.heights.to_dict(),
            "disagreement_sigma": self.disagreement_sigma,
            "u_rel": self.u_rel,
        }


@dataclass(frozen=True)
class IntrinsicsCalibration:
    """What a camera calibration found.

    ``intrinsics``: the camera model (image size, ``sigma`` for every fitted intrinsic, ``source``);
    ``rms_px``: re-projection error over every corner used (root mean square of the distance);
    ``views``: per-view diagnostics; ``fitted``: the intrinsics that were free; ``focal``: where the
    focal length came from.
    """

    intrinsics: CameraIntrinsics
    rms_px: float
    views: tuple[ViewDiagnostics, ...]
    fitted: tuple[str, ...]
    focal: FocalScale

    @property
    def corners(self) -> int:
        return sum(v.corners for v in self.views)

    def problems(
        self,
        *,
        focal_rel: float = 5e-4,
        principal_px: float = 1.0,
        rms_px: float = 0.1,
        k: float = 3.0,
        require_heights: bool = True,
    ) -> list[str]:
        """What keeps this calibration from the bounds, each with what to do; empty when it meets them.

        A bound is met when ``k`` standard uncertainties fit inside it: focal lengths within ``focal_rel``
        (relative), principal point within ``principal_px``; and the re-projection error is under
        ``rms_px``. With ``require_heights``, a focal length from tilted views alone is a problem too: a
        shallow depth of field biases it beyond what its uncertainty says (``TARGET.md``).
        """
        sigma, out = self.intrinsics.sigma, []
        if require_heights and self.focal.heights is None:
            out.append(
                "the focal length comes from tilted views alone, which the blur across them biases: take "
                "views square to the target at several heights, reading the distance sensor at each"
            )
        for name, value in (("fx", self.intrinsics.fx), ("fy", self.intrinsics.fy)):
            rel = k * sigma.get(name, math.inf) / value
            if not rel <= focal_rel:
                more = (
                    "more square views over a wider span of heights"
                    if self.focal.heights is not None
                    else "more views tilted further, keeping the target in focus"
                )
                out.append(f"{name} is known to {rel:.3%} ({k:g} sigma), not {focal_rel:.3%}: take {more}")
        for name in ("cx", "cy"):
            bound = k * sigma.get(name, math.inf)
            if not bound <= principal_px:
                out.append(
                    f"{name} is known to {bound:.2f} px ({k:g} sigma), not {principal_px:g} px: take more "
                    "tilted views, in more directions"
                )
        if not self.rms_px <= rms_px:
            out.append(
                f"the re-projection error is {self.rms_px:.3f} px, above {rms_px:g} px: check the target "
                "(clean, flat, the description matching it) and the focus, and look at the worst views"
            )
        return out

    def warnings(self) -> list[str]:
        """What is worth knowing though it does not fail the calibration."""
        out = []
        z = self.focal.disagreement_sigma
        if z is not None and abs(z) > AGREE_SIGMA:
            assert self.focal.heights is not None
            out.append(
                f"the tilted views' focal length is {self.focal.heights.kappa - 1.0:+.3%} from the heights' "
                f"({z:+.1f} sigma): the blur across tilted views moves their corners (a shallow depth of "
                "field); the heights' is used. Stop the lens down to bring them together"
            )
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the camera model's content, the fit's error, the focal length's source, the views."""
        return {
            "camera_model": self.intrinsics.to_dict(),
            "rms_px": self.rms_px,
            "corners": self.corners,
            "fitted": list(self.fitted),
            "focal": self.focal.to_dict(),
            "views": [v.to_dict() for v in self.views],
        }
