"""Synthetic ruler frames for the identification's tests and benchmarks: the calibration plan's ruler
configurations, seen by a true arm and camera, rendered by the ruler's twin and measured (issue 22).

The frames the calibration plan will take along the cell's rulers (:class:`RulerPlan`: the configuration
the bench uses, so that the plan can be built to match): for each ruler, at each position along it, the
camera square on the ruler at the capture distance, turned about its axis by each turn (plus a seeded
turn of up to ``turn_jitter_deg``), in up to ``max_solutions`` of the joint solutions the true arm's IK
finds; a few more frames off the capture plane (``depth_offsets_mm``), from which the sensor's offset
along the optical axis follows. Each frame: the arm goes to the recorded joints, where the camera
really is is the true kinematics plus the arm's repeatability (``arm_noise_mm`` per axis); the sensor
reads the ruler's glass along its beam when the beam falls on it (``sensor_noise_mm``), nothing
otherwise; the image is the ruler's twin (``sim.ruler.render_ruler``: the true camera, the preset, the
defocus of the frame's depth) measured by ``station.vision.measure_ruler`` with the nominal camera
model (the position under the principal point), or, without images (``rendered=False``, for fast tests),
the twin's exact truth with ``measure_noise_mm`` added. Truth for tests and benchmarks only.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from sim._render_camera import F4_DEFOCUS_PX_PER_MM, CameraSpec
from sim.cell_rulers import DEFAULT_RULERS, RulerMount, on_substrate, ray_hit, ruler_view
from sim.presets import get_preset
from sim.ruler import render_ruler, ruler_truth
from station.calibration import CameraModel, RulerObservation, RulerPlacement
from station.kinematics import Kinematics, rot_x, rot_y, rot_z, transform
from station.vision import MeasurementError, RulerParams, measure_ruler

FloatArray = npt.NDArray[np.float64]

TABLE_Z_MM = 328.9
"""The table's plane in the synthetic cell (the simulated world's, to 0.1 mm)."""

DEFOCUS_PX_PER_MM = F4_DEFOCUS_PX_PER_MM
"""The blur's growth away from focus (``sim.world.WorldSpec.defocus_px_per_mm``'s default: f/4)."""


@dataclass(frozen=True)
class RulerPlan:
    """The ruler configurations of a calibration (the bench's; the plan's should match).

    Attributes
    ----------
    positions_mm
        Where along each ruler the camera looks (mm): frames 10 to 240 mm apart.
    turns_deg
        The camera's turns about its optical axis, from the image's x along the ruler's +s.
    turn_jitter_deg
        A seeded turn of up to this much added to each.
    max_solutions
        Joint solutions per turn (of those the IK finds within the limits).
    lateral_mm
        A seeded offset of up to this much across the ruler (the pattern stays wholly in view).
    depth_offsets_mm
        Frames off the capture plane (further along the optical axis: +), at ``depth_positions_mm``,
        turn 0, the first solution.
    depth_positions_mm
        Where along each ruler the frames off the capture plane are taken.
    lean_deg, lean_azimuths_deg, lean_positions_mm
        Frames with the camera leaning ``lean_deg`` from square, toward each azimuth (from the ruler's
        +s, about its normal), the optical axis still meeting the ruler at the capture distance, at each
        of ``lean_positions_mm``, turn 0, the first solution: only views from other directions than
        the surface's normal place the camera along its optical axis (a shift along it looks, square
        on, like the ruler's height).
    """

    positions_mm: tuple[float, ...] = (5.0, 15.0, 45.0, 95.0, 155.0, 205.0, 245.0)
    turns_deg: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0)
    turn_jitter_deg: float = 20.0
    max_solutions: int = 2
    lateral_mm: float = 0.3
    depth_offsets_mm: tuple[float, ...] = (-1.5, 1.5)
    depth_positions_mm: tuple[float, ...] = (45.0, 205.0)
    lean_deg: float = 15.0
    lean_azimuths_deg: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0)
    lean_positions_mm: tuple[float, ...] = (15.0, 95.0, 205.0)


def taught_rulers(
    mounts: Sequence[RulerMount] = DEFAULT_RULERS, *, table_z_mm: float = TABLE_Z_MM
) -> dict[int, RulerPlacement]:
    """The rulers' placements as the cell's description gives them (the mounts' nominal frames)."""
    out = {}
    for k, mount in enumerate(mounts):
        F = mount.frame(table_z_mm)
        origin = (float(F[0, 3]), float(F[1, 3]), float(F[2, 3]))
        s_axis = (float(F[0, 0]), float(F[1, 0]), float(F[2, 0]))
        up = (-float(F[0, 2]), -float(F[1, 2]), -float(F[2, 2]))
        out[k] = RulerPlacement(origin, s_axis, up)
    return out


def true_ruler_frames(
    seed: int, mounts: Sequence[RulerMount] = DEFAULT_RULERS, *, table_z_mm: float = TABLE_Z_MM
) -> dict[int, FloatArray]:
    """Where the rulers really are: the mounts' frames moved by up to 1 mm and turned by up to 0.2 deg."""
    rng = np.random.default_rng([0x2B1, seed])
    out = {}
    for k, mount in enumerate(mounts):
        F = mount.frame(table_z_mm)
        a, b, c = np.radians(rng.uniform(-0.2, 0.2, 3))
        out[k] = transform(F[:3, :3] @ rot_x(a) @ rot_y(b) @ rot_z(c), F[:3, 3] + rng.uniform(-1.0, 1.0, 3))
    return out


def _reading(camera: FloatArray, mount: FloatArray, frame: FloatArray) -> float | None:
    """The sensor's distance along its beam to the ruler's glass, or None when the beam misses it."""
    head = camera @ mount
    hit = ray_hit(head[:3, 3], head[:3, 2], frame)
    return None if hit is None or not on_substrate(hit[0], hit[1]) else hit[2]


def _scale(homography: FloatArray, x: float, y: float) -> float:
    """``1 / |grad s|`` (px/mm) at pixel (x, y) of a ruler mm -> px homography."""
    G = np.linalg.inv(homography)
    a, _, w = G @ np.array([x, y, 1.0])
    grad = (G[0, :2] * w - a * G[2, :2]) / w**2
    return float(1.0 / np.hypot(*grad))


def ruler_session(
    kinematics: Kinematics,
    camera: CameraModel,
    mount: FloatArray,
    frames: Mapping[int, FloatArray],
    *,
    nominal: CameraModel,
    plan: RulerPlan = RulerPlan(),
    seed: int = 1,
    first_configuration: int = 10_000,
    rendered: bool = True,
    preset: str = "nominal",
    arm_noise_mm: float = 0.005,
    sensor_noise_mm: float = 0.002,
    measure_noise_mm: float = 2e-5,
    measure_scale_noise: float = 5e-6,
    refused: list[str] | None = None,
) -> list[RulerObservation]:
    """Frames of every ruler in ``frames`` by the plan (see the module notes).

    Parameters
    ----------
    kinematics, camera, mount
        The true arm (camera as the tool), the true camera (pinhole) and sensor mount (4x4).
    frames
        Each ruler's true frame (4x4, base frame), by id.
    nominal
        The camera model the station measures with (its principal point is the frames' reference).
    plan
        The configurations.
    seed
        Seeds the turns, offsets, the arm's and sensor's noise and the images' noise.
    first_configuration
        The configuration id of the first frame (keep them apart from the crossings').
    rendered
        Render and measure each frame; False: the twin's exact truth plus ``measure_noise_mm`` on ``s``
        and ``t`` and ``measure_scale_noise`` (relative) on the scale (the same poses, arm noise and
        readings either way).
    arm_noise_mm, sensor_noise_mm
        The arm's repeatability (each axis of the camera's position) and the sensor's (its reading).
    refused
        Collects the error code of each rendered frame the measurement refused (left out).
    """
    rng = np.random.default_rng([0x52, seed])
    image_rng = np.random.default_rng([0x53, seed])  # apart, so that rendered and exact frames share poses
    true_cam = CameraSpec(
        width=camera.width,
        height=camera.height,
        px_per_mm=camera.focal_px / nominal.working_distance_mm,
        working_distance_mm=nominal.working_distance_mm,
    )
    params = RulerParams(
        camera_matrix=[
            [nominal.focal_px, 0.0, nominal.principal_px[0]],
            [0.0, nominal.focal_px, nominal.principal_px[1]],
            [0.0, 0.0, 1.0],
        ],
        dist_coeffs=[0.0] * 5,
    )
    lean_params = params.with_values(max_tilt_deg=plan.lean_deg + 5.0)
    preset_values = get_preset(preset)
    depth = nominal.working_distance_mm
    out: list[RulerObservation] = []
    config = first_configuration
    for r, frame in frames.items():
        # position, turn, depth offset, lean azimuth (None: square), solutions
        targets: list[tuple[float, float, float, float | None, int]] = []
        for s in plan.positions_mm:
            targets += [(s, turn, 0.0, None, plan.max_solutions) for turn in plan.turns_deg]
        for s in plan.depth_positions_mm:
            targets += [(s, 0.0, dz, None, 1) for dz in plan.depth_offsets_mm]
        if plan.lean_deg:
            for s in plan.lean_positions_mm:
                targets += [(s, 0.0, 0.0, az, 1) for az in plan.lean_azimuths_deg]
        for s, turn, dz, azimuth, solutions in targets:
            psi = math.radians(turn + rng.uniform(-plan.turn_jitter_deg, plan.turn_jitter_deg))
            R = frame[:3, :3] @ rot_z(psi)
            if azimuth is not None:
                az = math.radians(azimuth)
                R = frame[:3, :3] @ rot_z(az) @ rot_y(math.radians(plan.lean_deg)) @ rot_z(-az) @ rot_z(psi)
            point = frame[:3, :3] @ np.array([s, rng.uniform(-plan.lateral_mm, plan.lateral_mm), 0.0])
            target = transform(R, frame[:3, 3] + point - (depth + dz) * R[:, 2])
            for q in kinematics.inverse_all(target)[:solutions]:
                actual = kinematics.tool_pose(q)
                actual[:3, 3] += rng.normal(0.0, arm_noise_mm, 3)
                T = np.asarray(np.linalg.solve(actual, frame), dtype=np.float64)
                pose, anchor = ruler_view(T, nominal.working_distance_mm)
                truth = ruler_truth(pose, anchor_mm=anchor, camera=true_cam)
                cx, cy = nominal.principal_px
                if rendered:
                    blur = math.hypot(preset_values.blur_sigma_px, DEFOCUS_PX_PER_MM * pose.z_mm)
                    image, _ = render_ruler(
                        pose,
                        anchor_mm=anchor,
                        preset=replace(preset_values, blur_sigma_px=blur),
                        camera=true_cam,
                        texture_seed=r,
                        rng=image_rng,
                    )
                    try:
                        m = measure_ruler(image, params if azimuth is None else lean_params)
                    except MeasurementError as exc:
                        if refused is not None:
                            refused.append(exc.code)
                        continue  # the plan would take the frame again; the fit goes without it
                    position, offset, scale = m.position_mm, m.offset_mm, float(m.extra["px_per_mm"])
                else:
                    h = truth.homography
                    noise = image_rng.normal(0.0, 1.0, 3)
                    position = truth.principal_position_mm + measure_noise_mm * float(noise[0])
                    offset = truth.principal_offset_mm + measure_noise_mm * float(noise[1])
                    scale = _scale(h, cx, cy) * (1.0 + measure_scale_noise * float(noise[2]))
                reading = _reading(actual, mount, frame)
                if reading is not None:
                    reading += float(rng.normal(0.0, sensor_noise_mm))
                joints = (float(q[0]), float(q[1]), float(q[2]), float(q[3]), float(q[4]), float(q[5]))
                out.append(RulerObservation(joints, position, offset, (cx, cy), scale, reading, config, r))
                config += 1
    return out


__all__ = [
    "DEFOCUS_PX_PER_MM",
    "TABLE_Z_MM",
    "RulerPlan",
    "ruler_session",
    "taught_rulers",
    "true_ruler_frames",
]
