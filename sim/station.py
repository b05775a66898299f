"""The whole simulated station in one object: controller twin, world, flange camera, table operator.

The arm is the controller twin on a real pseudo-terminal (talk to it with the real driver through
``port``); the world follows the twin's attained joints, so a joint move changes what the camera
sees; the operator answers the manual table's prompts on ``broker`` by turning the world's
micrometers. Start it at the world's reference pose, where the camera looks down at the crossing.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Literal

import numpy as np

from sim.camera import SimCamera
from sim.controller import ControllerTwin
from sim.distance_sensor import DistanceSensorTwin, HeadModel, world_source
from sim.operator import MicrometerFollower, SimOperator
from sim.world import World, WorldSpec
from station.config import (
    CalibrationConfig,
    CameraConfig,
    CameraMount,
    DistanceSensorConfig,
    RobotConfig,
    SensorMount,
    StationConfig,
    StationDevices,
    TableConfig,
    build,
)
from station.devices import DistanceSensor, Robot, XYTable
from station.kinds.calibration.plan import LOOK_DOWN, square_on
from station.kinematics import Kinematics, transform
from station.mounts import MountBody
from station.prompts import PromptBroker
from station.ruler_config import RulerConfig

#: The simulated Z sensor's mount in the camera frame: 30 mm beside the optical axis, beam parallel to
#: it, reference point in the camera's pinhole plane, so that it reads the working distance (68 mm, inside
#: the IL-065's 55-105 mm) when the crossing is in focus. Its head (for the keep-out): a 20 mm cylinder
#: behind the reference point.
SIM_SENSOR_MOUNT = SensorMount(
    translation_mm=(30.0, 0.0, 0.0),
    rotation_deg=(0.0, 0.0, 0.0),
    body=MountBody(radius_mm=20.0, z_from_mm=-70.0, z_to_mm=-10.0),
)

SIM_MAX_SPEED_PCT = 80.0
"""The simulated cell's speed cap: repeatability's default speed (80 %) until the sessions' pre-flight
refuses a plan above the cap (``station.speed_cap.check_plan_speeds``); a lab's default is 50 %."""

BENCH_TOP_Z_MM = 250.0
"""The bench the X-Y table and the angle blocks stand on (base frame, mm): below every artifact."""

PLATE_MM = 10.0
"""The thickness of each artifact's plate (its top face is the artifact's plane)."""


class SimStation:
    """Twin, world, camera and operator wired together; close it when done (or use ``with``).

    Parameters
    ----------
    spec
        The world (optics, table, preset); the twin starts at ``spec.reference_joints_deg``.
    seed
        Seeds the twin's repeatability error and the camera noise.
    twin_options
        Further :class:`sim.controller.TwinSettings` fields (``time_scale``, ``repeat_sigma_deg`` ...).
    sensor_mount
        Where the Z distance sensor twin sits in the camera frame; ``None``: no distance sensor.
    """

    def __init__(
        self,
        spec: WorldSpec | None = None,
        *,
        seed: int = 0,
        operator_delay_s: float = 0.0,
        camera_frame_rate_hz: float = 0.0,
        table_origin_in: tuple[float, float] = (0.0, 0.0),
        sensor_mount: SensorMount | None = SIM_SENSOR_MOUNT,
        **twin_options: Any,
    ) -> None:
        world_spec = spec or WorldSpec()
        options = {"time_scale": 100.0, "seed": seed, **twin_options}
        options.setdefault("start_pose_deg", world_spec.reference_joints_deg)
        self.twin = ControllerTwin(**options).start()
        self.world = World(world_spec, joints=self.twin.arm.actual_exact, seed=seed)
        self.camera = SimCamera(self.world, seed=seed, frame_rate_hz=camera_frame_rate_hz)
        self.broker = PromptBroker()
        self.operator = SimOperator(
            self.broker, self.world, origin_in=table_origin_in, delay_s=operator_delay_s
        ).start()
        self.follower: MicrometerFollower | None = None
        self.sensor_mount = sensor_mount
        self.distance_twin: DistanceSensorTwin | None = None
        if sensor_mount is not None:
            source = world_source(self.world, sensor_mount.matrix())
            head = HeadModel(plane_half_size_mm=world_spec.artifact_half_size_mm)  # one plate for both twins
            self.distance_twin = DistanceSensorTwin(source, head, seed=seed).start()

    @property
    def port(self) -> str:
        """The pty the controller twin serves: open the robot driver on it."""
        return self.twin.port

    def close(self) -> None:
        if self.follower is not None:
            self.follower.close()
        self.operator.close()
        self.camera.close()
        if self.distance_twin is not None:
            self.distance_twin.close()
        self.twin.close()

    def __enter__(self) -> SimStation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: Micrometer readings (in) at table position (0, 0) mm in the simulated station: mid-travel, so that a
#: pattern can be approached from either side.
SIM_TABLE_ORIGIN_IN = (0.5, 0.5)


def sim_camera_mount(world: World) -> CameraMount:
    """The simulated camera's mounting: the tool point along the flange's axis, not turned; its body a
    30 mm cylinder from the lens front back to the flange."""
    return CameraMount(translation_mm=(0.0, 0.0, float(world.spec.tool_length_mm)))


def sim_fixtures(world: World) -> list[dict[str, Any]]:
    """The simulated cell's fixtures as keep-out volumes (base frame, mm): the X-Y table's carriage and
    micrometers under the table's artifact, each artifact's plate (under its top face), and the angle
    block each bench artifact stands on, from the bench up to its plate's lowest edge."""
    table = world.artifact_poses()[0]
    x, y, top = (float(v) for v in table[:3, 3])
    volumes: list[dict[str, Any]] = [
        {
            "shape": "box",
            "name": "X-Y table",
            "center_mm": (x, y, (BENCH_TOP_Z_MM + top - PLATE_MM) / 2.0),
            "size_mm": (220.0, 220.0, top - PLATE_MM - BENCH_TOP_Z_MM),
        }
    ]
    half = world.spec.artifact_half_size_mm
    for k, T in enumerate(world.artifact_poses()):
        down = T[:3, 2]  # the artifact's normal points down into its plate
        centre = T[:3, 3] + down * PLATE_MM / 2.0
        rx, ry, rz = _xyz_angles_deg(T[:3, :3])
        name = "table artifact plate" if k == 0 else f"bench artifact {k} plate"
        volumes.append(
            {
                "shape": "box",
                "name": name,
                "center_mm": tuple(float(v) for v in centre),
                "size_mm": (2.0 * half, 2.0 * half, PLATE_MM),
                "rotation_deg": (rx, ry, rz),
            }
        )
        if k == 0:
            continue
        tilt = math.acos(min(1.0, abs(float(down[2]))))
        lowest = float(T[2, 3]) - half * math.sin(tilt) * math.sqrt(2.0) - PLATE_MM
        volumes.append(
            {
                "shape": "cylinder",
                "name": f"bench artifact {k} angle block",
                "base_mm": (float(T[0, 3]), float(T[1, 3]), BENCH_TOP_Z_MM),
                "radius_mm": 40.0,
                "height_mm": lowest - BENCH_TOP_Z_MM,
            }
        )
    return volumes


def _xyz_angles_deg(R: np.ndarray) -> tuple[float, float, float]:
    """``(rx, ry, rz)`` with ``R = rot_z(rz) @ rot_y(ry) @ rot_x(rx)`` (the mounts' and boxes' order)."""
    ry = math.asin(max(-1.0, min(1.0, -float(R[2, 0]))))
    rx = math.atan2(float(R[2, 1]), float(R[2, 2]))
    rz = math.atan2(float(R[1, 0]), float(R[0, 0]))
    return math.degrees(rx), math.degrees(ry), math.degrees(rz)


def sim_safety(world: World) -> dict[str, Any]:
    """The simulated cell's ``[robot] safety``: the artifact plane is the table plane, the camera's front
    (the tool point) must stay 40 mm above it (it works at 68 mm), the cell's fixtures are keep-out
    volumes (:func:`sim_fixtures`), and the speed cap is :data:`SIM_MAX_SPEED_PCT`.

    ``camera_offset_mm`` (the mounting's old, translation-only form) is kept beside ``[camera] mount``
    for the session code that still reads it; the configuration checks that the two agree.
    """
    return {
        "table_z_mm": float(world.artifact_poses()[0][2, 3]),  # the table's, wherever the arm is
        "camera_offset_mm": (0.0, 0.0, float(world.spec.tool_length_mm)),
        "min_camera_height_mm": 40.0,
        "max_step_deg": 30.0,
        "max_speed_pct": SIM_MAX_SPEED_PCT,
        "keep_out": sim_fixtures(world),
    }


def taught_artifacts_mm(world: World, *, digits: int | None = 1) -> list[tuple[float, float, float]]:
    """Each artifact's crossing as a person would teach it: the arm jogged until the true camera, square to
    the artifact, sees the crossing centred at the working distance, the position then read through the
    nominal kinematics (what WORLD reports) plus the working distance along the optical axis. Off the
    truth by the arm's kinematic errors (a millimetre or so), which the calibration plan's re-centring
    absorbs."""
    wd = world.spec.camera.working_distance_mm
    nominal = Kinematics(tool=world.kinematics.tool)
    out = []
    for T, up in zip(world.artifact_poses(), taught_normals(world), strict=True):
        camera = transform(square_on(up) @ LOOK_DOWN, T[:3, 3] + wd * np.asarray(up))
        q = world.kinematics.inverse(camera, seed_deg=world.spec.reference_joints_deg)
        taught = nominal.forward(q) @ np.array([0.0, 0.0, wd, 1.0])
        x, y, z = (float(v) if digits is None else round(float(v), digits) for v in taught[:3])
        out.append((x, y, z))
    return out


def taught_normals(world: World, *, digits: int | None = 3) -> list[tuple[float, float, float]]:
    """Each artifact's upward normal as measured on the bench (an inclinometer: to 0.001)."""
    return [
        tuple(-float(v) if digits is None else round(-float(v), digits) for v in T[:3, 2])  # type: ignore[misc]
        for T in world.artifact_poses()
    ]


def taught_turns_deg(world: World, *, digits: int | None = 1) -> list[float]:
    """Each artifact's yaw as a person would teach it: the camera turn (about its axis, from square on
    with the image's x along the base's -x, see ``station.kinds.calibration.plan``) at which the cross
    appears square."""
    out = []
    for T, up in zip(
        world.artifact_poses(), taught_normals(world, digits=None if digits is None else 3), strict=True
    ):
        u = (square_on(up) @ LOOK_DOWN).T @ T[:3, 0]
        turn = math.degrees(math.atan2(float(u[1]), float(u[0])))
        out.append(turn if digits is None else round(turn, digits))
    return out


def _rounded(v: np.ndarray, digits: int) -> tuple[float, float, float]:
    return (round(float(v[0]), digits), round(float(v[1]), digits), round(float(v[2]), digits))


def taught_rulers(world: World) -> list[RulerConfig]:
    """The cell's fixed rulers as a person would describe them: graduation 0's point and the direction
    read to 0.1 mm and 0.001 (a ruler on the table is where it was put; the fit finds the rest)."""
    return [
        RulerConfig(
            origin_mm=_rounded(F[:3, 3], 1),
            direction=_rounded(F[:3, 0], 3),
            normal=_rounded(-F[:3, 2], 3),
            name=mount.name,
        )
        for F, mount in zip(world.ruler_poses(), world.spec.rulers, strict=False)  # a table's ruler: last
    ]


def build_sim_station(
    *,
    spec: WorldSpec | None = None,
    seed: int = 0,
    time_scale: float = 100.0,
    operator_delay_s: float = 0.0,
    operator: bool = True,
    sensor_mount: SensorMount | None = SIM_SENSOR_MOUNT,
    max_speed_pct: float = SIM_MAX_SPEED_PCT,
    table_artifact: Literal["cross", "ruler"] | None = None,
    calibration_target: bool = False,
    **twin_options: Any,
) -> StationDevices:
    """Device factory (``station.sim``): the whole simulated station, built but not connected.

    The controller twin runs on its pty and the real CRS driver talks to it; the camera renders the
    world; the manual table's prompts go to the station's broker, answered by the simulated operator
    (``operator=False``: by a person through the API, the world's micrometers then follow what they
    confirm). The Z distance sensor twin (a Keyence IL-065 behind a DL-RS1A) runs on its own pty at
    ``sensor_mount`` in the camera frame, read by the real driver (``sensor_mount=None``: no sensor).
    ``max_speed_pct``: the cell's speed cap (``[robot] safety``). ``table_artifact``: what the X-Y table
    carries when the station starts (``WorldSpec.table_artifact``; None: the spec's); ``calibration_target``:
    the camera calibration's target lies there instead (``WorldSpec.calibration_target``); a session
    asks for what it needs and the simulated operator swaps it (``station.table_content``). ``truth`` is the
    :class:`SimStation` (tests and benchmarks only).
    """
    if table_artifact is not None:
        spec = replace(spec or WorldSpec(), table_artifact=table_artifact)
    if calibration_target:
        spec = replace(spec or WorldSpec(), calibration_target=True)
    sim = SimStation(
        spec,
        seed=seed,
        time_scale=time_scale,
        operator_delay_s=operator_delay_s,
        table_origin_in=SIM_TABLE_ORIGIN_IN,
        sensor_mount=sensor_mount,
        **twin_options,
    )
    try:
        if not operator:
            sim.operator.close()
            follower = MicrometerFollower(sim.broker, sim.world, origin_in=SIM_TABLE_ORIGIN_IN)
            sim.camera.before_grab = follower.sync
            sim.follower = follower
        safety = {**sim_safety(sim.world), "max_speed_pct": max_speed_pct}
        reference = tuple(float(a) for a in sim.world.spec.reference_joints_deg)
        sensor_config: DistanceSensorConfig | None = None
        sensor: DistanceSensor | None = None
        if sim.distance_twin is not None and sensor_mount is not None:
            sensor_config = DistanceSensorConfig(
                driver="keyence_il", options={"port": sim.distance_twin.port}, mount=sensor_mount
            )
            sensor = build("distance_sensor", "keyence_il", port=sim.distance_twin.port)
        config = StationConfig(
            name="sim",
            robot=RobotConfig(
                driver="crs_a465",
                options={"port": sim.port},
                safety=safety,
                reference_joints_deg=reference,
            ),
            camera=CameraConfig(driver="sim", options={"seed": seed}, mount=sim_camera_mount(sim.world)),
            table=TableConfig(driver="manual", options={"origin_in": SIM_TABLE_ORIGIN_IN}, prompts="api"),
            distance_sensor=sensor_config,
            calibration=CalibrationConfig(
                artifacts_mm=taught_artifacts_mm(sim.world),
                artifact_turns_deg=taught_turns_deg(sim.world),
                artifact_normals=taught_normals(sim.world),
                working_distance_mm=sim.world.spec.camera.working_distance_mm,
                pixel_mm=1.0 / sim.world.spec.camera.px_per_mm,
                rulers=taught_rulers(sim.world),
            ),
        )
        robot: Robot = build("robot", "crs_a465", port=sim.port, safety=config.robot_safety())
        table: XYTable = build("table", "manual", broker=sim.broker, origin_in=SIM_TABLE_ORIGIN_IN)
    except BaseException:
        sim.close()
        raise
    return StationDevices(
        config=config,
        camera=sim.camera,
        broker=sim.broker,
        robot=robot,
        table=table,
        distance_sensor=sensor,
        owned=[sim],
        truth=sim,
        robot_options={"port": sim.port},
    )
