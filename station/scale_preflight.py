"""Every session's scale check (issue 23): the camera model and the distance against the groove's width.

Before anything moves, a session that captures the artifact grabs one frame where the camera is and
compares, with :func:`station.camcal.check_scale`, the groove widths it measures (px) with what the
station believes: the camera model (``[camera] camera_model``, else the nominal pinhole of ``[calibration]
pixel_mm`` and ``working_distance_mm``) at the distance in use (the distance sensor's reading through its
mount, else the working distance), for the artifact's width (the station's scale calibration, else the
drawing's 1/32 in, +0/-0.002 in). Beyond :data:`~station.camcal.SCALE_CHECK_LIMIT` (0.2 %) the session
is refused with what to do. Where the crossing is not in view before the first move (a session that
routes the arm to it), or the arm is away from the reference pose (where a previous session left it: the
camera may see the grooves askew, foreshortened), the check is made on the session's first measured
capture instead, and fails the session there; a plan that only warns is always checked on its first
capture (no frame of its own). A camera model made for another image size than the camera's frames is
refused outright.

A plan says how the check applies to it with an optional ``scale_check`` attribute: ``"fail"`` (the
default), ``"warn"`` (a validation, the session that measures the artifact's width: a disagreement is
reported and its own groove-width gate judges) or ``"skip"`` (a camera calibration: the camera sees its
target, not the artifact, and the session is what sets the camera model).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from station.arm_route import at_pose
from station.camcal import SCALE_CHECK_LIMIT, ScaleCheckError, check_scale, distance_from_sensor
from station.camera_model import CameraIntrinsics, CameraModelError, check_image_size, read_camera_model
from station.config import StationDevices
from station.devices import DeviceError
from station.plans import CaptureResult, Plan
from station.plans._gates import GateError
from station.vision import MeasurementError, MeasureParams, measure

__all__ = ["DRAWING_TOLERANCE_MM", "ScaleBasis", "ScalePreflight", "scale_check_mode"]

log = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
Mode = Literal["fail", "warn", "skip"]
Emit = Callable[[str, dict[str, Any]], None]

DRAWING_TOLERANCE_MM = (-0.0508, 0.0)
"""How far below and above the drawing's 1/32 in the grooves may be: +0/-0.002 in (mm)."""


SQUARE_TOLERANCE_DEG = 1.0
"""The pre-flight checks the frame where the arm is only when every joint is within this of the session's
reference pose (the camera square to the artifact: a tilt of 1 deg narrows the grooves by 0.015 %, of
12 deg by 2.2 %); elsewhere (where the last session left it) the check waits for the first capture."""


def _at_reference(devices: StationDevices) -> bool:
    robot, reference = devices.robot, devices.reference_joints_deg
    if robot is None or reference is None:
        return True  # no arm: the camera looks as it was set up to
    try:
        here = robot.where().commanded_joints_deg
    except DeviceError:
        return False  # the session's own moves will say what is wrong; the check waits for its capture
    return at_pose(here, reference, SQUARE_TOLERANCE_DEG)


def scale_check_mode(plan: Plan, params: Any = None, devices: StationDevices | None = None) -> Mode:
    """How the scale check applies to ``plan`` (its ``scale_check``: a mode, or a method of the session's
    ``params`` and ``devices`` for a plan whose sessions differ, e.g. a calibration that identifies the
    magnification itself along rulers; ``"skip"`` for a plan that drives no camera)."""
    if "camera" not in plan.needs:
        return "skip"
    mode = getattr(plan, "scale_check", "fail")
    if callable(mode):
        mode = mode(params, devices)
    for known in ("fail", "warn", "skip"):
        if mode == known:
            return known
    raise ValueError(f"plan {plan.name!r}: scale_check must be 'fail', 'warn' or 'skip', got {mode!r}")


@dataclass(frozen=True)
class ScaleBasis:
    """What the station believes about the image's scale: the camera model (``model_from`` says where it
    came from), the working distance (None: unknown), the sensor's mount in the camera frame (None: no
    sensor), the artifact's width and the interval around it its true width can be in (``width_from``)."""

    intrinsics: CameraIntrinsics
    model_from: str
    working_distance_mm: float | None
    sensor_mount: FloatArray | None
    groove_width_mm: float
    tolerance_mm: tuple[float, float]
    width_from: str
    undistorted: bool


class ScalePreflight:
    """The scale check of one session: :meth:`before_motion` in its pre-flight, then, if the crossing was
    not in view there, :meth:`first_capture` after each step until a capture is measured.

    ``emit(kind, data)`` records what it found (the runner's events: ``scale_check``, ``warning``).
    """

    def __init__(
        self,
        devices: StationDevices | None,
        plan: Plan,
        measure_params: MeasureParams,
        scale_calibration: Mapping[str, Any] | None,
        emit: Emit,
        plan_params: Any = None,
    ) -> None:
        self._devices = devices
        self._mode: Mode = "skip" if devices is None else scale_check_mode(plan, plan_params, devices)
        self._params = measure_params
        self._scale_calibration = scale_calibration
        self._emit = emit
        self._basis: ScaleBasis | None = None
        self.pending = False
        """True while the check waits for the session's first measured capture."""

    def before_motion(self) -> list[str]:
        """The pre-flight's problems (none, or the scale check's or the image size's refusal)."""
        devices = self._devices
        if self._mode == "skip" or devices is None:
            return []
        config = devices.config
        if config.camera.camera_model is None and config.calibration is None:
            self._emit(
                "warning",
                {
                    "message": "no scale check: the station has no camera model ([camera] camera_model) and "
                    "no nominal optics ([calibration] pixel_mm and working_distance_mm)"
                },
            )
            return []
        if self._mode == "warn":
            self.pending = True  # a warning need not stop anything: its first capture, no frame of its own
            return []
        if not _at_reference(devices):
            self.pending = True  # the camera may see the artifact askew from here: its first capture
            return []
        try:
            frame = devices.camera.grab()
        except DeviceError as exc:
            return [f"the camera cannot be read: {exc}"]
        height, width = frame.image.shape[:2]
        try:
            self._basis = _basis(devices, self._params, self._scale_calibration, (width, height))
        except CameraModelError as exc:  # ImageSizeError among them: never measure with that model
            return [str(exc)]
        if self._basis is None:
            return []
        try:
            m = measure(frame.image, self._params)
        except MeasurementError:
            self.pending = True  # the crossing is not in view before the first move: its first capture
            return []
        z_mm, z_note = self._read_z()
        problem = self._check(
            [float(v) for v in m.groove_width_px],
            float(m.rotation_deg),
            (float(m.center_px[0]), float(m.center_px[1])),
            z_mm,
            "pre-flight",
            z_note,
        )
        return [] if problem is None or self._mode == "warn" else [problem]

    def first_capture(self, captures: Sequence[CaptureResult]) -> None:
        """The check on the session's first measured capture of the crossing (while :attr:`pending`);
        raises GateError with what to do when it fails."""
        if not self.pending:
            return
        for c in captures:
            m = c.measurement
            if m is None or not m.get("ok") or c.meta.get("role") == "align":
                continue
            self.pending = False
            if self._basis is None and not self._basis_from(c):
                return
            diag = m.get("diagnostics") or {}
            widths = diag.get("groove_width_px")
            if not isinstance(widths, list) or len(widths) != 2:
                return
            z_note = None if c.z_mm is not None else c.meta.get("z_error")
            problem = self._check(
                [float(v) for v in widths],
                float(diag.get("rotation_deg", 0.0)),
                (float(m["center_px"][0]), float(m["center_px"][1])),
                c.z_mm,
                f"capture {c.capture_id}",
                z_note,
            )
            if problem is not None and self._mode == "fail":
                raise GateError(problem)
            return

    # ------------------------------------------------------------------ internals

    def _basis_from(self, capture: CaptureResult) -> bool:
        """The basis for the frames of ``capture`` (a check deferred from pre-flight): True when there is
        one; a model for another image size fails the session (``fail``) or is reported (``warn``)."""
        assert self._devices is not None
        try:
            self._basis = _basis(
                self._devices, self._params, self._scale_calibration, (capture.width, capture.height)
            )
        except CameraModelError as exc:
            if self._mode == "fail":
                raise GateError(str(exc)) from exc
            self._report(str(exc))
            return False
        return self._basis is not None

    def _read_z(self) -> tuple[float | None, str | None]:
        sensor = self._devices.distance_sensor if self._devices is not None else None
        if sensor is None:
            return None, None
        try:
            return float(sensor.read_mm()), None
        except (DeviceError, ValueError) as exc:
            return None, f"the distance sensor gave no reading ({exc})"

    def _check(
        self,
        widths_px: list[float],
        rotation_deg: float,
        center_px: tuple[float, float],
        z_mm: float | None,
        where: str,
        z_note: str | None,
    ) -> str | None:
        """Compare; record the outcome (event ``scale_check``); the problem (a warning in ``warn`` mode)."""
        basis = self._basis
        assert basis is not None
        if z_mm is not None and basis.sensor_mount is not None:
            distance, distance_from = distance_from_sensor(z_mm, basis.sensor_mount), "the distance sensor"
        elif basis.working_distance_mm is not None:
            distance, distance_from = basis.working_distance_mm, "the working distance"
        else:
            self._emit(
                "warning",
                {
                    "message": "no scale check: no distance (no sensor reading"
                    + (f": {z_note}" if z_note else "")
                    + ") and no [calibration] working_distance_mm"
                },
            )
            return None
        try:
            check = check_scale(
                basis.intrinsics,
                distance_mm=distance,
                groove_width_px=widths_px,
                groove_width_mm=basis.groove_width_mm,
                width_tolerance_mm=basis.tolerance_mm,
                rotation_deg=rotation_deg,
                center_px=center_px,
                undistorted=basis.undistorted,
            )
        except ScaleCheckError as exc:
            refused = f"scale check ({where}): {exc}"
            self._report(refused)
            return refused
        verdict = check.problem(SCALE_CHECK_LIMIT)
        problem = (
            None
            if verdict is None
            else f"{verdict} [{where}; model: {basis.model_from}; width: {basis.width_from}]"
        )
        self._emit(
            "scale_check",
            {
                **check.to_dict(),
                "passed": problem is None,
                "limit": SCALE_CHECK_LIMIT,
                "where": where,
                "distance_mm": distance,
                "distance_from": distance_from,
                "model_from": basis.model_from,
                "width_from": basis.width_from,
                "severity": self._mode,
            },
        )
        if problem is not None:
            self._report(problem)
        return problem

    def _report(self, problem: str) -> None:
        log.warning("%s", problem)
        if self._mode == "warn":
            self._emit("warning", {"message": problem})


def _basis(
    devices: StationDevices,
    params: MeasureParams,
    scale_calibration: Mapping[str, Any] | None,
    frame_size: tuple[int, int],
) -> ScaleBasis | None:
    """What the station believes (None: no camera model and no nominal optics to check). Raises
    CameraModelError for a model file that cannot be read or holds for another image size."""
    config = devices.config
    nominal = config.calibration
    wd = None if nominal is None else float(nominal.working_distance_mm)
    path: Path | None = config.camera.camera_model
    width, height = frame_size
    if path is not None:
        intrinsics = read_camera_model(path)
        check_image_size(intrinsics, width, height, require_size=False)
        model_from = f"camera model {path}"
    elif nominal is not None:
        f = nominal.working_distance_mm / nominal.pixel_mm
        K = np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
        intrinsics = CameraIntrinsics(K, np.zeros(5), (width, height))
        model_from = "the nominal optics ([calibration] pixel_mm, working_distance_mm)"
    else:
        return None
    cal = scale_calibration
    if cal is not None and _finite(cal.get("groove_width_mm")) and _finite(cal.get("u_mm")):
        width_mm, u = float(cal["groove_width_mm"]), float(cal["u_mm"])
        tolerance = (-2.0 * u, 2.0 * u)
        width_from = f"the scale calibration's {width_mm:.5f} mm +/- {2.0 * u:.5f} mm"
    else:
        width_mm, tolerance = float(params.groove_width_mm), DRAWING_TOLERANCE_MM
        width_from = f"the drawing's {width_mm:.4f} mm, +0/-0.0508 mm"
    return ScaleBasis(
        intrinsics,
        model_from,
        wd,
        devices.distance_sensor_mount,
        width_mm,
        tolerance,
        width_from,
        params.camera_matrix is not None,
    )


def _finite(v: object) -> bool:
    return isinstance(v, int | float) and math.isfinite(v) and v > 0
