"""The camera's intrinsics from views of the target: OpenCV's calibration, with uncertainties and diagnostics.

``cv2.calibrateCameraExtended`` (Zhang's method refined by Levenberg-Marquardt over every corner of every
view) from the station's nominal camera as the starting point; one pass that leaves out corners whose
re-projection error is beyond ``outlier_px`` (a misdetected corner) and fits again; the standard
uncertainties are OpenCV's ``stdDeviationsIntrinsics`` (the Jacobian's covariance scaled by the residual
variance).

Notes
-----
With a 6.4 x 4.8 mm field at 68 mm the camera sees +/-2.7 deg: a target square to it shows the focal
length only through ``f / distance``, which any focal length fits with another distance. What separates
them is perspective: tilted views, where the image scale changes across the target by the depth change
over the distance. So the views must be tilted (``TARGET.md``: how many, how far, and what depth of field
allows), and the focal length's uncertainty says whether they were. Principal point and tangential
distortion trade off in the same way; ``tangential=False`` fits them out when the lens has none to speak of.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from station.camcal._detect import TargetDetection
from station.camcal._errors import CalibrationFitError, TooFewViewsError
from station.camcal._heights import SensorReading, height_scale
from station.camcal._result import FocalScale, IntrinsicsCalibration, ViewDiagnostics
from station.camcal._target import STANDARD_TARGET, CharucoTarget
from station.camera_model import DIST_NAMES, CameraIntrinsics

__all__ = ["FitOptions", "calibrate_intrinsics"]

FloatArray = npt.NDArray[np.float64]

MIN_VIEWS = 3
_INTRINSIC_NAMES = ("fx", "fy", "cx", "cy", *DIST_NAMES[:5])


@dataclass(frozen=True)
class FitOptions:
    """Which of OpenCV's intrinsics the fit frees.

    ``radial``: radial coefficients fitted (1: k1; 2: k1, k2; 3: k1, k2, k3); ``tangential``: p1 and p2;
    ``fix_aspect``: ``fx / fy`` kept at the starting camera's; ``outlier_px``: corners re-projecting
    farther than this after the first fit are left out of the second (0: keep every corner).

    The defaults suit the station's +/-2.7 deg field: k1 alone (k2 moves the corner of the image by
    ``k2 r^5 f``, 1e-6 px per unit: nothing a view can see), no tangential terms (across so narrow a field
    they look like a shift of the principal point and a tilt: fitting them multiplied the principal
    point's uncertainty by 5-8 on the twin, ``TARGET.md``). A lens with decentred elements: ``tangential``.
    """

    radial: int = 1
    tangential: bool = False
    fix_aspect: bool = False
    outlier_px: float = 0.5

    def __post_init__(self) -> None:
        if self.radial not in (1, 2, 3):
            raise ValueError(f"radial must be 1, 2 or 3 coefficients, got {self.radial}")
        if not (math.isfinite(self.outlier_px) and self.outlier_px >= 0):
            raise ValueError(f"outlier_px must be a finite value >= 0, got {self.outlier_px}")

    def flags(self) -> int:
        flags = cv2.CALIB_USE_INTRINSIC_GUESS
        flags |= {1: cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3, 2: cv2.CALIB_FIX_K3, 3: 0}[self.radial]
        if not self.tangential:
            flags |= cv2.CALIB_ZERO_TANGENT_DIST
        if self.fix_aspect:
            flags |= cv2.CALIB_FIX_ASPECT_RATIO
        return int(flags)

    def fitted(self) -> tuple[str, ...]:
        """Names of the intrinsics the fit frees."""
        names = ["fx", "fy", "cx", "cy", *("k1", "k2", "k3")[: self.radial]]
        if self.tangential:
            names += ["p1", "p2"]
        return tuple(names)


def _check_inputs(detections: Sequence[TargetDetection], guess: CameraIntrinsics) -> tuple[int, int]:
    if len(detections) < MIN_VIEWS:
        raise TooFewViewsError(
            f"{len(detections)} views of the target; a calibration needs at least {MIN_VIEWS}, tilted in "
            "different directions (TARGET.md recommends about 48)"
        )
    sizes = {d.image_size for d in detections}
    if len(sizes) != 1:
        raise TooFewViewsError(
            f"the views have different image sizes {sorted(sizes)}: take every view with one camera setting"
        )
    size = sizes.pop()
    if guess.image_size is not None and guess.image_size != size:
        raise TooFewViewsError(
            f"the starting camera model holds for {guess.image_size[0]} x {guess.image_size[1]} px but the "
            f"views are {size[0]} x {size[1]} px: start from the nominal camera at this size"
        )
    few = [i for i, d in enumerate(detections) if d.count < 4]
    if few:
        raise TooFewViewsError(f"views {few} have fewer than 4 corners: leave them out or take them again")
    return size


def calibrate_intrinsics(
    detections: Sequence[TargetDetection],
    *,
    guess: CameraIntrinsics,
    readings: Sequence[SensorReading | None] | None = None,
    target: CharucoTarget = STANDARD_TARGET,
    options: FitOptions = FitOptions(),
    reading_u_mm: float = 0.001,
    sensor_scale_u_rel: float = 0.0,
    source: dict[str, Any] | None = None,
    pose_only: Sequence[bool] | None = None,
) -> IntrinsicsCalibration:
    """Calibrate the camera's intrinsics from views of ``target``.

    Parameters
    ----------
    detections : sequence of TargetDetection
        One per view (``detect_target``), all of one image size; at least 3, and tilted (see Notes of
        the module).
    guess : CameraIntrinsics
        The nominal camera to start from (focal length from the configured pixel size and working
        distance, principal point at the image centre).
    readings : sequence of SensorReading or None, optional
        The distance sensor's reading for each view (None for a view without one). With readings of
        views square to the target at several heights, the focal lengths' scale comes from them
        (``station.camcal._heights``) and the rest is fitted again with it fixed.
    target : CharucoTarget
        The target seen (its pitch's certificate enters the heights' uncertainty; recorded in ``source``).
    options : FitOptions
        Which intrinsics are free, and the outlier threshold.
    reading_u_mm, sensor_scale_u_rel : float
        One reading's standard uncertainty (mm) and the sensor's relative scale uncertainty over the
        heights used (its linearity; the twin's is exact, a real head's comes from its certificate).
    source : dict, optional
        More provenance for the model's ``source`` (a session id, the date).
    pose_only : sequence of bool, optional
        Views that take no part in the intrinsics' fit: only their poses are found (``cv2.solvePnP`` with
        the fitted intrinsics), for the heights. The square views followed into the blur
        (``follow_target``): their corners are noisier than the in-focus views' and would only inflate
        the re-projection error and the uncertainties OpenCV scales by it.

    Returns
    -------
    IntrinsicsCalibration
        The camera model with its image size and uncertainties, the re-projection error, where the focal
        length came from, and each view's diagnostics.

    Raises
    ------
    TooFewViewsError
        Fewer than 3 views, views of different sizes, a view with fewer than 4 corners, readings not one
        per view, or readings but no square views at two heights.
    CalibrationFitError
        OpenCV's fit failed, or gave a camera beyond plausibility (focal length more than 20 % from the
        guess, principal point outside the frame).
    """
    width, height = _check_inputs(detections, guess)
    if readings is not None and len(readings) != len(detections):
        raise TooFewViewsError(
            f"{len(readings)} sensor readings for {len(detections)} views: give one per view"
        )
    only = [False] * len(detections) if pose_only is None else [bool(p) for p in pose_only]
    if len(only) != len(detections):
        raise ValueError("pose_only needs one entry per view")
    fitted_idx = [i for i, p in enumerate(only) if not p]
    if len(fitted_idx) < MIN_VIEWS:
        raise TooFewViewsError(
            f"{len(fitted_idx)} views in focus for the intrinsics' fit; a calibration needs at least "
            f"{MIN_VIEWS}, tilted in different directions"
        )
    obj = [detections[i].object_mm.astype(np.float32) for i in fitted_idx]
    img = [detections[i].corners_px.astype(np.float32) for i in fitted_idx]
    flags = options.flags()
    K, dist, rvecs, tvecs, std = _fit(
        obj, img, (width, height), guess.camera_matrix, guess.dist_coeffs, flags
    )
    kept = [np.ones(detections[i].count, dtype=bool) for i in fitted_idx]
    if options.outlier_px > 0:
        errors = [_errors(o, p, r, t, K, dist) for o, p, r, t in zip(obj, img, rvecs, tvecs, strict=True)]
        kept = [e <= options.outlier_px for e in errors]
        if not all(k.all() for k in kept):
            if any(int(k.sum()) < 4 for k in kept):
                raise CalibrationFitError(
                    "a view keeps fewer than 4 corners within "
                    f"{options.outlier_px} px of the fit: leave it out, or check the target's description"
                )
            obj = [o[k] for o, k in zip(obj, kept, strict=True)]
            img = [p[k] for p, k in zip(img, kept, strict=True)]
            K, dist, rvecs, tvecs, std = _fit(
                obj, img, (width, height), guess.camera_matrix, guess.dist_coeffs, flags
            )
    _plausible(K, guess, width, height)
    sigma = {name: float(std[_INTRINSIC_NAMES.index(name)]) for name in options.fitted()}
    focal = FocalScale(float(K[0, 0]), sigma["fx"] / float(K[0, 0]), None)
    if readings is not None:
        views_now = _all_views(detections, fitted_idx, obj, img, rvecs, tvecs, kept, K, dist, options)
        poses = [_pose(v[2], v[3]) for v in views_now]
        scale = height_scale(
            [p[1] for p in poses],
            [p[0] for p in poses],
            readings,
            reading_u_mm=reading_u_mm,
            pitch_u_rel=target.certificate.pitch_u_rel,
            sensor_scale_u_rel=sensor_scale_u_rel,
        )
        focal = FocalScale(focal.tilted_fx_px, focal.tilted_u_rel, scale)
        K0 = K.copy()
        K0[0, 0] /= focal.scale
        K0[1, 1] /= focal.scale
        K, dist, rvecs, tvecs, std = _fit(
            obj, img, (width, height), K0, dist, flags | cv2.CALIB_FIX_FOCAL_LENGTH
        )
        _plausible(K, guess, width, height)
        sigma = {name: float(std[_INTRINSIC_NAMES.index(name)]) for name in options.fitted()}
        sigma["fx"], sigma["fy"] = float(K[0, 0]) * focal.u_rel, float(K[1, 1]) * focal.u_rel
    everything = _all_views(detections, fitted_idx, obj, img, rvecs, tvecs, kept, K, dist, options)
    views, squares = [], []
    for i, (o, p, r, t, k) in enumerate(everything):
        e = _errors(o, p, r, t, K, dist)
        if not only[i]:
            squares.append(e * e)
        tilt, distance = _pose(r, t)
        views.append(
            ViewDiagnostics(
                index=i,
                corners=int(o.shape[0]),
                dropped=int(k.size - k.sum()),
                rms_px=float(np.sqrt(np.mean(e * e))),
                max_px=float(np.max(e)),
                coverage=detections[i].coverage(),
                tilt_deg=tilt,
                distance_mm=distance,
                rvec=tuple(float(v) for v in np.ravel(r)),  # type: ignore[arg-type]
                tvec_mm=tuple(float(v) for v in np.ravel(t)),  # type: ignore[arg-type]
                pose_only=only[i],
            )
        )
    model = CameraIntrinsics(
        K,
        dist,
        (width, height),
        sigma=sigma,
        source={
            "method": "opencv calibrateCameraExtended",
            "focal_from": focal.source,
            "views": len(detections),
            "target": target.model_dump(),
            **(source or {}),
        },
    )
    rms = float(np.sqrt(np.mean(np.concatenate(squares))))
    return IntrinsicsCalibration(model, rms, tuple(views), options.fitted(), focal)


View = tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], FloatArray, FloatArray, npt.NDArray[np.bool_]]


def _all_views(
    detections: Sequence[TargetDetection],
    fitted_idx: list[int],
    obj: list[npt.NDArray[np.float32]],
    img: list[npt.NDArray[np.float32]],
    rvecs: list[FloatArray],
    tvecs: list[FloatArray],
    kept: list[npt.NDArray[np.bool_]],
    K: FloatArray,
    dist: FloatArray,
    options: FitOptions,
) -> list[View]:
    """Every view's corners used, pose and kept mask, in the detections' order: the fitted views' from the
    fit, the pose-only views' by ``solvePnP`` with the intrinsics ``K``, ``dist`` (corners beyond the
    outlier threshold left out and the pose found again)."""
    out: dict[int, View] = {
        i: (o, p, r, t, k) for i, o, p, r, t, k in zip(fitted_idx, obj, img, rvecs, tvecs, kept, strict=True)
    }
    for i, d in enumerate(detections):
        if i in out:
            continue
        o, p = d.object_mm.astype(np.float32), d.corners_px.astype(np.float32)
        r, t = _solve_pose(o, p, K, dist)
        k = np.ones(d.count, dtype=bool)
        if options.outlier_px > 0:
            k = _errors(o, p, r, t, K, dist) <= options.outlier_px
            if int(k.sum()) < 4:
                raise CalibrationFitError(
                    f"view {i} keeps fewer than 4 corners within {options.outlier_px} px of its pose: "
                    "leave it out, or take the square views nearer focus"
                )
            if not k.all():
                o, p = o[k], p[k]
                r, t = _solve_pose(o, p, K, dist)
        out[i] = (o, p, r, t, k)
    return [out[i] for i in range(len(detections))]


def _solve_pose(
    obj: npt.NDArray[np.float32], img: npt.NDArray[np.float32], K: FloatArray, dist: FloatArray
) -> tuple[FloatArray, FloatArray]:
    ok, r, t = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise CalibrationFitError("a square view's pose could not be found: take it again")
    return np.asarray(r, dtype=np.float64), np.asarray(t, dtype=np.float64)


def _pose(rvec: FloatArray, tvec: FloatArray) -> tuple[float, float]:
    """A view's tilt (deg, the target's normal against the optical axis) and distance along the axis (mm)."""
    normal = cv2.Rodrigues(rvec)[0][:, 2]
    t = np.asarray(tvec, dtype=np.float64).ravel()
    tilt = math.degrees(math.acos(min(1.0, abs(float(normal[2])))))
    return tilt, float(normal @ t) / float(normal[2])


def _fit(
    obj: list[npt.NDArray[np.float32]],
    img: list[npt.NDArray[np.float32]],
    size: tuple[int, int],
    K_start: FloatArray,
    dist_start: FloatArray,
    flags: int,
) -> tuple[FloatArray, FloatArray, list[FloatArray], list[FloatArray], FloatArray]:
    K0 = np.array(K_start, dtype=np.float64)
    d0 = np.zeros(5)
    d0[: min(5, dist_start.size)] = dist_start[:5]
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    try:
        _rms, K, dist, rvecs, tvecs, std, _ext, _per_view = cv2.calibrateCameraExtended(
            obj, img, size, K0, d0, flags=flags, criteria=criteria
        )
    except cv2.error as exc:
        raise CalibrationFitError(
            f"OpenCV's calibration failed: {exc.err}; check the views and the target"
        ) from exc
    K_out = np.asarray(K, dtype=np.float64)
    dist_out = np.asarray(dist, dtype=np.float64).ravel()[:5]
    std_out = np.asarray(std, dtype=np.float64).ravel()
    if not (np.all(np.isfinite(K_out)) and np.all(np.isfinite(dist_out))):
        raise CalibrationFitError(
            "the calibration diverged (non-finite values): take more, and more tilted, views"
        )
    rv = [np.asarray(r, dtype=np.float64) for r in rvecs]
    return K_out, dist_out, rv, [np.asarray(t, dtype=np.float64) for t in tvecs], std_out


def _errors(
    obj: npt.NDArray[np.float32],
    img: npt.NDArray[np.float32],
    r: FloatArray,
    t: FloatArray,
    K: FloatArray,
    dist: FloatArray,
) -> FloatArray:
    proj, _ = cv2.projectPoints(obj, r, t, K, dist)
    return np.asarray(np.hypot(*(proj.reshape(-1, 2) - img.reshape(-1, 2)).T), dtype=np.float64)


def _plausible(K: FloatArray, guess: CameraIntrinsics, width: int, height: int) -> None:
    for name, value, nominal in (("fx", K[0, 0], guess.fx), ("fy", K[1, 1], guess.fy)):
        if not abs(value / nominal - 1.0) <= 0.2:
            raise CalibrationFitError(
                f"the fit's {name} = {value:.1f} px is {value / nominal - 1.0:+.0%} from the nominal "
                f"{nominal:.1f} px: the views do not determine the focal length (tilt them more) or the "
                "configured pixel size and working distance are wrong"
            )
    cx, cy = K[0, 2], K[1, 2]
    if not (0 <= cx <= width - 1 and 0 <= cy <= height - 1):
        raise CalibrationFitError(
            f"the fit's principal point ({cx:.1f}, {cy:.1f}) px is outside the {width} x {height} frame: "
            "the views do not determine it; take more views tilted in different directions"
        )
