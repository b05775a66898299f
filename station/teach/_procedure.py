"""Teaching with the devices: the readings a taught value needs, taken from the robot, the camera and the
distance sensor directly (as the manual tools do), and the value computed (``_maths``).

Every motion is a small move (``station.jog``) through the model teaching reads through (the nominal
one, or a calibrated arm: ``_model``), checked on the robot (limits, step, keep-out along the path,
speed cap) before it is sent, at the jog speed. Readings are taken at the encoders' joints. The arm is
left where the taught value was read: at the reference pose, at the square pose over the artifact, or
back where the sensor mount's heights started.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np
import numpy.typing as npt

from station.arm_route import Route, max_step_of, route_problems, split_move, step_limit
from station.camera_model import CameraIntrinsics, read_camera_model
from station.config import StationConfig, StationDevices
from station.devices import Camera, DistanceSensor, MotionRejectedError, Robot
from station.jog import JOG_SPEED_PCT, camera_jog_target, camera_offset_target
from station.kinematics import Kinematics
from station.teach._maths import (
    Plane,
    SensorOffsetFit,
    TeachError,
    crossing_on_plane,
    fit_plane,
    fit_sensor_offset,
    pose_to_see,
    sensor_point,
    square_turn_deg,
    wrist_turns_deg,
)
from station.teach._model import TeachModel
from station.vision import MeasureParams, measure

__all__ = [
    "SENSOR_HEIGHTS_MM",
    "TaughtArtifact",
    "TaughtReference",
    "TeachRig",
    "camera_intrinsics",
    "rig_for",
    "teach_artifact",
    "teach_reference",
    "teach_sensor_mount",
]

log = logging.getLogger(__name__)
FloatArray = npt.NDArray[np.float64]

SENSOR_HEIGHTS_MM = (-1.5, -0.75, 0.0, 0.75, 1.5)
"""Camera moves along the optical axis (+ toward the artifact) at which ``teach_sensor_mount`` reads."""
PLANE_SPREAD_MM = 15.0
"""The sensor reads the artifact's plane at four points this far along the camera's x and y from the
point the camera looks at (off both grooves, around the crossing: the plane is not extrapolated)."""
WRIST_SAMPLES = 4
"""Readings a plane read by turning the wrist takes: one on each diagonal between the grooves."""


@dataclass
class TeachRig:
    """What teaching reads and moves: the devices (connected), the nominal model (``nominal``: the arm's
    nominal kinematics with the camera's mounting as its tool), the camera model, the sensor's mount in
    the camera frame (4x4), the working distance, the jog speed, and the model teaching reads through
    when it is not the nominal one (``model``: a calibrated arm, ``station.teach.TeachModel``)."""

    robot: Robot
    camera: Camera
    sensor: DistanceSensor | None
    nominal: Kinematics
    intrinsics: CameraIntrinsics
    sensor_mount: FloatArray | None
    working_distance_mm: float
    speed_pct: float = 10.0
    readings: int = 5
    measure_params: MeasureParams = field(default_factory=MeasureParams)
    model: TeachModel | None = None
    max_step_deg: float = 30.0

    @property
    def kinematics(self) -> Kinematics:
        """What teaching reads and moves through: ``model``'s (a calibrated arm) when given, else the
        nominal model."""
        return self.nominal if self.model is None else self.model.kinematics

    @property
    def model_source(self) -> dict[str, Any]:
        """Which model teaching reads through (``TeachModel.source``): recorded with the taught value."""
        return {"model": "nominal"} if self.model is None else dict(self.model.source)

    def joints(self) -> tuple[float, ...]:
        """The commanded joints (deg): where the next move starts from."""
        return tuple(float(v) for v in self.robot.where().commanded_joints_deg)

    def attained(self) -> tuple[float, ...]:
        """The encoders' joints (deg): what a reading is taken at (the controller's set-point misses it by
        the joints' backlash and noise, which the encoders see), as the calibration's observations are."""
        return tuple(float(v) for v in self.robot.where().joints_deg)

    def move(self, target: Sequence[float]) -> None:
        """A checked move (limits, step, keep-out along the path) at the jog speed."""
        self.robot.check_move(target)
        self.robot.check_speed(self.speed_pct)
        self.robot.set_speed(self.speed_pct)
        self.robot.move_joints(target)

    def reading_mm(self) -> float:
        if self.sensor is None:
            raise TeachError(
                "teaching this needs the distance sensor ([distance_sensor] in the configuration)"
            )
        values = [self.sensor.read_mm() for _ in range(self.readings)]
        return float(np.mean(values))

    def crossing(self) -> tuple[tuple[float, float], float]:
        """The measured crossing (px) and the rotation of the groove nearest the image's x (deg)."""
        frame = self.camera.grab()
        m = measure(frame.image, self.measure_params)
        return (float(m.center_px[0]), float(m.center_px[1])), float(m.rotation_deg)

    def plane(self) -> Plane:
        """The artifact's plane through the rig's model (``plane_samples``)."""
        return self.plane_samples().plane(self.kinematics)

    def plane_samples(self, groove_deg: float | None = None) -> PlaneSamples:
        """Sensor readings around the point the camera looks at, with the encoders' joints of each (the
        arm comes back): through a calibrated arm with the grooves' direction known (``groove_deg``, the
        measured groove nearest the image's x), the wrist turned (:meth:`wrist_samples`), else the camera
        shifted (:meth:`shifted_samples`).

        Read through an arm model, a plane's normal carries what that model gets wrong between the
        points: shifted, the gradient of its position error (the joints 1-3 move); turned, the
        orientation of the wrist's axis alone (joint 6 moves). A calibration from crossings pins the
        latter (0.009-0.011 deg on the simulated day one's calibrated arm, without noise) but not the
        former (0.011-0.116 deg there); the nominal model's errors are of one size either way (0.015-0.081
        shifted, 0.080-0.162 turned). Taught there: 0.007-0.024 deg turned, 0.012-0.116 shifted."""
        if self.model is not None and groove_deg is not None:
            turned = self.wrist_samples(groove_deg)
            if turned is not None:
                return turned
        return self.shifted_samples()

    def shifted_samples(self) -> PlaneSamples:
        """Sensor readings at four points around the one the camera looks at (the camera shifted in its
        own x and y so that the beam lands there; the arm comes back), with the encoders' joints of each."""
        if self.sensor_mount is None:
            raise TeachError("teaching a plane needs the distance sensor and its mount")
        start = self.joints()
        bx, by = float(self.sensor_mount[0, 3]), float(self.sensor_mount[1, 3])
        samples = []
        try:
            for a, b in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
                shift = (a * PLANE_SPREAD_MM - bx, b * PLANE_SPREAD_MM - by, 0.0)
                q = camera_offset_target(start, self.kinematics, shift)
                self.move(q)
                samples.append((self.attained(), self.reading_mm()))
        finally:
            self.move(start)
        return PlaneSamples(self.sensor_mount, tuple(samples))

    def wrist_samples(self, groove_deg: float) -> PlaneSamples | None:
        """Sensor readings with only the wrist (joint 6) turned, so that the beam's spot circles the
        optical axis and lands on each diagonal between the grooves (``wrist_turns_deg``), with the
        encoders' joints of each; the arm comes back. Every move is checked before the first is sent
        (a turn the robot refuses, a joint limit or the keep-out, is left out; three must remain). None
        when the sensor's beam cannot circle the axis (not along the wrist, or on it)."""
        if self.sensor_mount is None:
            raise TeachError("teaching a plane needs the distance sensor and its mount")
        start = self.joints()
        turns = wrist_turns_deg(self.kinematics, start, self.sensor_mount, groove_deg)
        if turns is None:
            return None
        step = step_limit(self.max_step_deg)
        chosen: list[tuple[float, ...]] = []
        refused: list[str] = []
        diagonals: set[int] = set()
        for turn in turns:
            diagonal = round((turn - turns[0]) / 90.0) % 4
            if diagonal in diagonals:
                continue
            target = (*start[:5], round(start[5] + turn, 3))
            problems = route_problems(
                self.robot, Route(start, target, tuple(split_move(start, target, step)), False)
            )
            if not problems:
                chosen.append(target)
                diagonals.add(diagonal)
            else:
                refused.append(f"{turn:+.0f} deg: {problems[0]}")
            if len(chosen) == WRIST_SAMPLES:
                break
        if len(chosen) < 3:
            raise TeachError(
                "the wrist cannot turn far enough here to read the plane around the crossing ("
                + "; ".join(refused)
                + "); jog joint 6 toward the middle of its range, or the arm away from what it would hit,"
                " and teach again"
            )
        chosen.sort(key=lambda q: q[5])
        legs = [split_move(a, b, step) for a, b in pairwise([start, *chosen, start])]
        problems = route_problems(
            self.robot, Route(start, start, tuple(q for leg in legs for q in leg), False)
        )
        if problems:  # all checked before the first move
            raise MotionRejectedError(f"the wrist's turns are refused, nothing moved: {'; '.join(problems)}")
        samples = []
        try:
            for leg in legs[:-1]:
                for q in leg:
                    self.move(q)
                samples.append((self.attained(), self.reading_mm()))
        finally:
            for q in split_move(self.joints(), start, step):
                self.move(q)
        return PlaneSamples(self.sensor_mount, tuple(samples))


@dataclass(frozen=True)
class PlaneSamples:
    """The sensor's readings of a plane (mm), each with the encoders' joints it was read at (deg): the
    plane through any arm model (the sensor's mount in the camera frame)."""

    sensor_mount: FloatArray
    samples: tuple[tuple[tuple[float, ...], float], ...]

    def plane(self, kinematics: Kinematics) -> Plane:
        return fit_plane([sensor_point(kinematics.forward(q), self.sensor_mount, r) for q, r in self.samples])


@dataclass(frozen=True)
class TaughtReference:
    """The reference pose (``joints_deg``), the crossing it sees (``center_px``) and the plane's fit."""

    joints_deg: tuple[float, ...]
    center_px: tuple[float, float]
    crossing_mm: tuple[float, float, float]
    plane_rms_mm: float


@dataclass(frozen=True)
class TaughtArtifact:
    """An artifact as taught: its crossing (mm), upward normal, square turn (deg), the joints it was
    read from (the square pose), and the plane's fit."""

    position_mm: tuple[float, float, float]
    normal: tuple[float, float, float]
    turn_deg: float
    joints_deg: tuple[float, ...]
    center_px: tuple[float, float]
    plane_rms_mm: float


def _focus(rig: TeachRig, *, square: bool) -> None:
    """Bring the camera to the working distance from the plane the sensor reads (squared to it with
    ``square``) before the crossing is measured: a defocused view measures poorly."""
    plane = rig.plane()
    here = rig.kinematics.forward(rig.joints())
    on_axis = crossing_on_plane(here, rig.intrinsics.principal_point, rig.intrinsics, plane)
    normal = plane.normal if square else None
    target = pose_to_see(rig.joints(), rig.kinematics, on_axis, rig.working_distance_mm, normal=normal)
    rig.move(tuple(round(float(v), 3) for v in target))


def _crossing_mm(rig: TeachRig, plane: Plane) -> tuple[FloatArray, tuple[float, float], float]:
    center, rotation = rig.crossing()
    point = crossing_on_plane(rig.kinematics.forward(rig.attained()), center, rig.intrinsics, plane)
    return point, center, rotation


def teach_reference(rig: TeachRig, *, rounds: int = 2) -> TaughtReference:
    """The pose that sees the table's crossing on the principal point at the working distance, with the
    camera's orientation as the operator jogged it: focused by the sensor, measured, moved there,
    measured again (``rounds``)."""
    _focus(rig, square=False)
    for _ in range(rounds):
        plane = rig.plane()
        point, _, _ = _crossing_mm(rig, plane)
        rig.move(
            tuple(
                round(float(v), 3)
                for v in pose_to_see(rig.joints(), rig.kinematics, point, rig.working_distance_mm)
            )
        )
    samples = rig.plane_samples()
    center, _ = rig.crossing()
    # the crossing as the nominal model reads it, calibrated or not (see ``teach_artifact``)
    point = crossing_on_plane(
        rig.nominal.forward(rig.attained()), center, rig.intrinsics, samples.plane(rig.nominal)
    )
    return TaughtReference(
        rig.joints(),
        center,
        (float(point[0]), float(point[1]), float(point[2])),
        samples.plane(rig.kinematics).rms_mm,
    )


def teach_artifact(rig: TeachRig, *, rounds: int = 2) -> TaughtArtifact:
    """An artifact under the camera (its crossing in view): its plane from the sensor, the camera squared
    to it with the crossing centred at the working distance (``rounds`` times), then its crossing, normal
    and square turn read there."""
    _focus(rig, square=True)
    for _ in range(rounds):
        plane = rig.plane()
        point, _, _ = _crossing_mm(rig, plane)
        target = pose_to_see(
            rig.joints(), rig.kinematics, point, rig.working_distance_mm, normal=plane.normal
        )
        rig.move(tuple(round(float(v), 3) for v in target))
    # the crossing and the joints it is seen at first: the plane's readings move the arm
    center, rotation = rig.crossing()
    at = rig.attained()
    samples = rig.plane_samples(groove_deg=rotation)
    plane = samples.plane(rig.kinematics)
    turn = square_turn_deg(rig.kinematics.forward(at), center, rotation, rig.intrinsics, plane)
    n = plane.normal
    # The crossing's position stays the nominal model's reading at the same pose, calibrated or not: the
    # frame every plan moves in, and one that a calibration from crossings alone does not hold (it
    # leaves the camera's distance along its axis loose by millimetres); the orientation is the model's.
    point = crossing_on_plane(rig.nominal.forward(at), center, rig.intrinsics, samples.plane(rig.nominal))
    return TaughtArtifact(
        (float(point[0]), float(point[1]), float(point[2])),
        (float(n[0]), float(n[1]), float(n[2])),
        turn,
        rig.joints(),
        center,
        plane.rms_mm,
    )


def teach_sensor_mount(
    rig: TeachRig, *, heights_mm: Sequence[float] = SENSOR_HEIGHTS_MM
) -> tuple[SensorOffsetFit, list[tuple[float, float]]]:
    """The sensor mount's offset along the optical axis, from readings at known camera heights.

    The camera must be square to a flat surface with it in focus, i.e. at the working distance (the
    reference pose over the table's artifact, jogged until the crossing is sharp): the camera is moved
    along its optical axis by ``heights_mm`` (through the rig's model), the sensor read at each, and
    the arm brought back. Returns the fit and the (distance, reading) pairs.
    """
    if rig.sensor_mount is None:
        raise TeachError("teaching the sensor's mount needs the distance sensor")
    start = rig.joints()
    pairs: list[tuple[float, float]] = []
    try:
        for h in heights_mm:
            q = camera_jog_target(start, rig.kinematics, "z", h) if h else start
            rig.move(q)
            pairs.append((rig.working_distance_mm - h, rig.reading_mm()))
    finally:
        rig.move(start)
    fit = fit_sensor_offset([d for d, _ in pairs], [r for _, r in pairs], rig.sensor_mount)
    return fit, pairs


def camera_intrinsics(config: StationConfig, camera: Camera) -> CameraIntrinsics:
    """The station's camera model: ``[camera] camera_model``, else the nominal pinhole from
    ``[calibration]`` ``working_distance_mm`` and ``pixel_mm`` with the principal point at the centre of
    the camera's frame (one frame is grabbed for its size)."""
    if config.camera.camera_model is not None:
        return read_camera_model(config.camera.camera_model)
    if config.calibration is None:
        raise TeachError(
            "no camera model: set [camera] camera_model, or [calibration] working_distance_mm and pixel_mm"
            " (the optics' nominal values)"
        )
    height, width = camera.grab().image.shape[:2]
    f = config.calibration.working_distance_mm / config.calibration.pixel_mm
    K = np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
    return CameraIntrinsics(K, np.zeros(5), (width, height))


def rig_for(
    devices: StationDevices, *, speed_pct: float | None = None, model: TeachModel | None = None
) -> TeachRig:
    """The rig of a station's devices (connected) and configuration: the nominal model with ``[camera]
    mount``, the camera model (``[camera] camera_model``, else the nominal pinhole from ``[calibration]``
    ``working_distance_mm`` and ``pixel_mm`` with the principal point at the frame's centre), the sensor's
    mount, the jog speed (``[robot] safety.jog_speed_pct``, default 10 %), and ``model``: the calibrated
    arm to read through (None: the nominal model)."""
    config = devices.config
    if devices.robot is None:
        raise TeachError("teaching needs the robot ([robot] in the configuration)")
    if config.calibration is None:
        raise TeachError(
            "teaching needs [calibration] working_distance_mm and pixel_mm (the optics' nominal values)"
        )
    wd = config.calibration.working_distance_mm
    intrinsics = camera_intrinsics(config, devices.camera)
    safety = config.robot.safety if config.robot is not None else {}
    speed = float(safety.get("jog_speed_pct", JOG_SPEED_PCT)) if speed_pct is None else speed_pct
    return TeachRig(
        robot=devices.robot,
        camera=devices.camera,
        sensor=devices.distance_sensor,
        nominal=Kinematics(tool=config.camera_frame("teaching").matrix()),
        intrinsics=intrinsics,
        sensor_mount=devices.distance_sensor_mount,
        working_distance_mm=wd,
        speed_pct=speed,
        model=model,
        max_step_deg=max_step_of(safety),
    )
