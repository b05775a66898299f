"""The self-test's rig: the devices it drives, the models it compares with, and its small checked moves."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from station.arm_route import max_step_of
from station.camera_model import CameraIntrinsics
from station.config import StationConfig
from station.devices import Camera, MotionRejectedError, Robot
from station.jog import JOG_SPEED_PCT
from station.kinematics import Kinematics
from station.teach import camera_intrinsics
from station.vision import MeasureParams, measure

__all__ = ["DEFAULT_READY_POSE_DEG", "HALT_SPEED_PCT", "SelftestRig", "free", "offset", "selftest_rig"]

DEFAULT_READY_POSE_DEG = (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)
"""Where ``ready`` is assumed to go when the configuration does not say (DIALECT.md, still assumed 4)."""
HALT_SPEED_PCT = 5.0
"""The halt is tested at this speed (the self-test's "low speed")."""


@dataclass
class SelftestRig:
    """What the self-test drives and compares with: the robot and camera (connected); ``nominal`` the
    arm's nominal model with the camera's mounting as its tool; ``arm_model`` the station's arm model
    (flange) that WORLD is compared with; the camera model; the working distance; the ready pose; the
    largest joint step (for the route back after ``ready``) and the speeds (within the cap)."""

    robot: Robot
    camera: Camera
    nominal: Kinematics
    intrinsics: CameraIntrinsics
    working_distance_mm: float
    ready_pose_deg: tuple[float, ...] | None
    max_step_deg: float
    arm_model: Kinematics = field(default_factory=Kinematics)
    speed_pct: float = 10.0
    halt_speed_pct: float = HALT_SPEED_PCT
    measure_params: MeasureParams = field(default_factory=MeasureParams)
    clock: Callable[[], float] = time.monotonic

    def commanded(self) -> tuple[float, ...]:
        return tuple(float(v) for v in self.robot.where().commanded_joints_deg)

    def speed(self, percent: float) -> None:
        self.robot.check_speed(percent)
        self.robot.set_speed(percent)

    def move(self, target: Sequence[float]) -> None:
        """A checked move at the rig's speed."""
        self.robot.check_move(target)
        self.speed(self.speed_pct)
        self.robot.move_joints(target)

    def view(self) -> tuple[tuple[float, float], float, float]:
        """The crossing (px), its groove nearest the image's x (deg) and the grooves' mean width (px)."""
        m = measure(self.camera.grab().image, self.measure_params)
        width = float(np.mean(m.groove_width_px))
        return (float(m.center_px[0]), float(m.center_px[1])), float(m.rotation_deg), width


def _offset(q: Sequence[float], axis: int, delta: float) -> tuple[float, ...]:
    out = [float(v) for v in q]
    out[axis - 1] = round(out[axis - 1] + delta, 3)
    return tuple(out)


def _free(robot: Robot, target: Sequence[float], start: Sequence[float]) -> bool:
    try:
        robot.check_move(target, start_deg=start)
    except MotionRejectedError:
        return False
    return True


def offset(q: Sequence[float], axis: int, delta: float) -> tuple[float, ...]:
    """``q`` with joint ``axis`` (1-6) moved by ``delta`` (deg, to the 3 decimals the controller takes)."""
    out = [float(v) for v in q]
    out[axis - 1] = round(out[axis - 1] + delta, 3)
    return tuple(out)


def free(robot: Robot, target: Sequence[float], start: Sequence[float]) -> bool:
    """Whether the robot's host checks (limits, step, keep-out along the path) let ``start`` -> ``target``."""
    try:
        robot.check_move(target, start_deg=start)
    except MotionRejectedError:
        return False
    return True


def selftest_rig(
    config: StationConfig,
    robot: Robot,
    camera: Camera,
    *,
    ready_pose_deg: Sequence[float] | None = None,
    max_step_deg: float | None = None,
) -> SelftestRig:
    """The rig of a station's configuration and its robot and camera (connected): the nominal model with
    ``[camera] mount``, the camera model (:func:`station.teach.camera_intrinsics`), the working distance
    (``[calibration]`` ``working_distance_mm``), and the jog speed (``[robot] safety.jog_speed_pct``).

    ``ready_pose_deg`` and ``max_step_deg`` ``None``: the configuration's (``[robot] safety``), else the
    driver's defaults as the station knows them (``DEFAULT_READY_POSE_DEG``, DIALECT.md's assumption, and
    ``station.arm_route.DEFAULT_MAX_STEP_DEG``); a caller holding the driver passes its ``guard.limits``'.
    """
    if config.calibration is None:
        raise ValueError(
            "the self-test needs [calibration] working_distance_mm (and pixel_mm without [camera]"
            " camera_model): the optics' nominal values"
        )
    safety = config.robot.safety if config.robot is not None else {}
    if ready_pose_deg is None:
        ready_pose_deg = tuple(safety.get("ready_pose_deg", DEFAULT_READY_POSE_DEG))
    return SelftestRig(
        robot=robot,
        camera=camera,
        nominal=Kinematics(tool=config.camera_frame("the self-test").matrix()),
        intrinsics=camera_intrinsics(config, camera),
        working_distance_mm=config.calibration.working_distance_mm,
        ready_pose_deg=tuple(float(v) for v in ready_pose_deg),
        max_step_deg=max_step_of(safety) if max_step_deg is None else max_step_deg,
        speed_pct=float(safety.get("jog_speed_pct", JOG_SPEED_PCT)),
    )
