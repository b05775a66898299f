"""The camera calibration's results: the fitted intrinsics with their uncertainties as the typed results
(``results.CameraCalibrationResults``), the gates, and the model written on a passed calibration only."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from station.camcal import IntrinsicsCalibration
from station.camera_model import DIST_NAMES, CameraIntrinsics
from station.kinds.camera_calibration.model_file import write_with_history
from station.plans._gates import Check, checks_json

__all__ = ["Bounds", "calibration_results"]


def _estimate(model: CameraIntrinsics, name: str, value: float) -> dict[str, Any]:
    sigma = model.sigma.get(name)
    return {"value": float(value), "sigma": None if sigma is None else float(sigma)}


@dataclass(frozen=True)
class Bounds:
    """What a calibration must meet: focal lengths within ``focal_pct`` (%), principal point within
    ``principal_px``, each by ``k`` standard uncertainties (``IntrinsicsCalibration.problems``)."""

    focal_pct: float = 0.05
    principal_px: float = 1.0
    k: float = 3.0


def calibration_results(
    cal: IntrinsicsCalibration,
    bounds: Bounds,
    *,
    taken: int,
    missed: Sequence[str],
    camera_model: str | None,
    data_dir: Path,
) -> dict[str, Any]:
    """The session's results (``CameraCalibrationResults``) and gates; the model written (with the one it
    replaces kept) when the calibration meets ``bounds``, never otherwise."""
    model = cal.intrinsics
    problems = cal.problems(focal_rel=bounds.focal_pct / 100.0, principal_px=bounds.principal_px, k=bounds.k)
    gates = [Check("intrinsics_bounds", not problems, None, 0.0, "fail", p) for p in problems] or [
        Check(
            "intrinsics_bounds",
            True,
            None,
            0.0,
            "fail",
            f"focal lengths within {bounds.focal_pct:g} %, principal point within "
            f"{bounds.principal_px:g} px ({bounds.k:g} sigma), re-projection < 0.1 px",
        )
    ]
    gates += [Check("focal_agreement", False, None, 0.0, "warn", w) for w in cal.warnings()]
    if missed:
        gates.append(
            Check(
                "views_found",
                False,
                float(len(missed)),
                0.0,
                "warn",
                f"the target was not found in {len(missed)} of {taken} views ({missed[0]}): check the "
                "focus and the lighting",
            )
        )
    passed = not problems
    doc = model.to_dict()
    written = write_with_history(model, camera_model, data_dir) if passed else None
    if written is not None and not written.configured:
        gates.append(
            Check(
                "camera_model_configured",
                False,
                None,
                0.0,
                "warn",
                f"the camera model was written to the data directory's {written.path.name} (the results' "
                "camera_model_file): set [camera] camera_model to that path in the station configuration "
                "for sessions to use it",
            )
        )
    dist = [float(v) for v in np.ravel(model.dist_coeffs)]
    assert model.image_size is not None
    return {
        "passed": passed,
        "fx": _estimate(model, "fx", model.fx),
        "fy": _estimate(model, "fy", model.fy),
        "cx": _estimate(model, "cx", model.principal_point[0]),
        "cy": _estimate(model, "cy", model.principal_point[1]),
        "distortion": {n: _estimate(model, n, v) for n, v in zip(DIST_NAMES, dist, strict=False)},
        "rms_px": float(cal.rms_px),
        "image_size": list(model.image_size),
        "views": len(cal.views),
        "views_taken": taken,
        "corners": cal.corners,
        "focal_source": cal.focal.source,
        "focal": cal.focal.to_dict(),
        "camera_model": doc,
        "camera_model_file": None if written is None else str(written.path),
        "previous_model_file": None if written is None or written.previous is None else str(written.previous),
        "problems": problems,
        "warnings": cal.warnings(),
        "view_diagnostics": [v.to_dict() for v in cal.views],
        "checks": checks_json(gates),
    }
