"""The station's configuration (``station.toml``: its models, loading and snapshot) and the device
registry, which builds concrete devices by name without importing them.

Drivers (``drivers/``) and twins (``sim/``) register factories under the entry-point group
``station.devices`` with names ``KIND.NAME`` (``robot.crs_a465``, ``robot.sim``, ``camera.aravis`` ...),
so that the core never imports them (README, "Layout": dependencies point inward).
"""

from __future__ import annotations

import inspect
import logging
import math
import os
import tomllib
import uuid
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from station._pydantic import problems as describe
from station.compute import CLUSTER_HELP, ComputeSpec, parse_cluster
from station.devices import Camera, DistanceSensor, Robot, XYTable
from station.mounts import (
    LEGACY_CAMERA_OFFSET_KEY,
    CameraMount,
    MountConflictError,
    SensorMount,
    camera_mount_of,
    robot_safety_fields,
)
from station.prompts import PromptBroker
from station.redaction import redact
from station.ruler_config import RulerConfig

log = logging.getLogger(__name__)

DEVICE_GROUP = "station.devices"

ROBOT_LATCH_FILE = "robot-stop-latch.json"
"""The robot's stop latch in the data directory (``drivers/crs_a465/_latch.py``)."""


class ConfigurationError(ValueError):
    """The station configuration names something that does not exist or cannot be built."""


def _factories() -> dict[str, Any]:
    return {ep.name: ep for ep in entry_points(group=DEVICE_GROUP)}


def available(kind: str) -> list[str]:
    """Names registered for ``kind`` (e.g. ``available("robot") == ["crs_a465", "sim"]``)."""
    prefix = kind + "."
    return sorted(name[len(prefix) :] for name in _factories() if name.startswith(prefix))


def factory(kind: str, name: str) -> Callable[..., Any]:
    """The registered factory for ``KIND.NAME``; ConfigurationError naming the choices if absent."""
    eps = _factories()
    key = f"{kind}.{name}"
    if key not in eps:
        choices = ", ".join(available(kind)) or "none registered (is the project installed with pip -e?)"
        raise ConfigurationError(f"no {kind} named {name!r}; available: {choices}")
    loaded = eps[key].load()
    if not callable(loaded):
        raise ConfigurationError(f"entry point {key} is not callable")
    return loaded


def build(kind: str, name: str, /, **options: Any) -> Any:
    """Build the device ``KIND.NAME`` with keyword ``options``."""
    log.debug("building %s.%s with %s", kind, name, sorted(options))
    make = factory(kind, name)
    try:
        inspect.signature(make).bind(**options)
    except TypeError as exc:
        raise ConfigurationError(f"{kind}.{name}: bad options {sorted(options)}: {exc}") from exc
    except ValueError:  # no signature to check (a builtin): let the call say it
        pass
    return make(**options)


# --------------------------------------------------------------------------- the station configuration


class DeviceConfig(BaseModel):
    """One device: the registered driver (``KIND.DRIVER`` in ``station.devices``) and its options."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    driver: str = Field(min_length=1, description="registered name, e.g. crs_a465, aravis, v4l2, manual")
    options: dict[str, Any] = Field(default_factory=dict, description="keyword arguments of its factory")


class RobotConfig(DeviceConfig):
    """The arm: driver, options, safety limits (the driver's fields) and the session's reference pose."""

    safety: dict[str, Any] = Field(default_factory=dict, description="the driver's safety-limit fields")
    reference_joints_deg: tuple[float, float, float, float, float, float] = Field(
        description="the pose where the camera sees the artifact's crossing (deg)"
    )

    @field_validator("reference_joints_deg")
    @classmethod
    def _finite(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if not all(math.isfinite(a) for a in v):
            raise ValueError(f"reference_joints_deg must be finite angles, got {v}")
        return v


class CameraConfig(DeviceConfig):
    """The flange camera, with an optional camera model (intrinsics and distortion) for undistortion,
    and its mounting on the flange (``station.mounts.CameraMount``: translation and rotation, lens front,
    body), which gives the calibration its nominal camera frame and the keep-out its camera body."""

    camera_model: Path | None = Field(None, description="JSON or OpenCV YAML/XML camera model file")
    mount: CameraMount | None = Field(
        None, description="the camera frame in the flange frame; default: [robot] safety.camera_offset_mm"
    )


class TableConfig(DeviceConfig):
    """The X-Y table; ``prompts`` says who answers the manual table's prompts when run from the CLI."""

    prompts: Literal["terminal", "api"] = "terminal"


class DistanceSensorConfig(DeviceConfig):
    """The Z distance sensor beside the camera: driver, options and its mount in the camera frame."""

    mount: SensorMount = Field(
        default_factory=SensorMount, description="the sensor's pose in the camera frame"
    )


class ApiConfig(BaseModel):
    """The service (``station serve``): its access token and whether reads need it."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    token: str | None = Field(
        None,
        description="the API token (else $STATION_API_TOKEN), at least 16 characters",
    )
    open_reads: bool = Field(
        False, description="reads (sessions, images, the camera) without the token, as --public-read"
    )
    allow_remote_motion: bool = Field(
        False,
        description="let clients on other machines start and resume sessions and move the arm, as"
        " --allow-remote-motion (else only clients on the station itself: someone there sees the arm)",
    )


class ComputeConfig(BaseModel):
    """Where offline sessions measure (``[compute]``; ``station.compute``)::

        [compute]
        cluster = "tcp://10.0.0.5:8786"   # a Dask scheduler; "local" (default) or "local:4"
        ship_images = false               # true: send the frames' bytes (workers without the share)

    ``station run --cluster`` overrides it for one session; the service uses it for every re-analysis
    and sweep started from the API or the page.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    cluster: str = Field("local", description=CLUSTER_HELP)
    ship_images: bool = Field(False, description="send the frames' bytes to the workers")

    @field_validator("cluster")
    @classmethod
    def _known_cluster(cls, v: str) -> str:
        return parse_cluster(v)

    @model_validator(mode="after")
    def _ship_needs_cluster(self) -> ComputeConfig:
        self.spec()  # ValueError for ship_images without a cluster
        return self

    def spec(self, jobs: int = 1) -> ComputeSpec:
        """The backend this section names (the local pool with ``jobs`` processes)."""
        return ComputeSpec(self.cluster, jobs, self.ship_images)


class CalibrationConfig(BaseModel):
    """What the calibration plan must know of the cell (``[calibration]``)::

        [calibration]
        artifacts_mm = [[482, 0, 329], [350, 250, 380]]   # taught crossing positions, base frame
        artifact_turns_deg = [0, 30]                        # the camera turn that sees each cross square
        artifact_normals = [[0, 0, 1], [0, 0.34, 0.94]]     # each top plane's upward normal (default level)
        working_distance_mm = 68
        pixel_mm = 0.01                                     # object-side pixel at the working distance

    ``artifacts_mm``: where each artifact's crossing is (base frame, mm) as taught with the nominal
    kinematics (jog until the crossing is centred and in focus, read WORLD, add the working distance
    along the optical axis); within about 2 mm is enough: the plan re-centres by measurement.
    ``artifact_turns_deg``: for each, the turn of the camera about its axis (from looking straight down
    with the image's x along the base's -x) at which the cross appears square in the image (its yaw, as
    taught; default 0): the plan's turns are relative to it, so precise mode sees the cross within its
    +/-40 deg and the kinematic model says which groove is which. ``artifact_normals``: each artifact's
    upward normal in the base frame (default level); an artifact on an angle block makes the camera,
    square to it, bend the wrist sideways, which the calibration needs to tell the wrist's links apart.
    The turn is then measured in the frame that the smallest rotation from level to that normal gives.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    artifacts_mm: list[tuple[float, float, float]] = Field(min_length=1)
    artifact_turns_deg: list[float] | None = None
    artifact_normals: list[tuple[float, float, float]] | None = None
    working_distance_mm: float = Field(gt=0, le=1000)
    pixel_mm: float = Field(gt=0, le=1.0, description="object-side pixel size at the working distance")
    artifact_names: list[str] | None = Field(
        None, description="a name for each artifact (station teach artifact NAME); default 1, 2, ..."
    )
    rulers: list[RulerConfig] = Field(default_factory=list, description="the cell's rulers (issue 22)")

    @field_validator("artifacts_mm")
    @classmethod
    def _finite_positions(cls, v: list[tuple[float, float, float]]) -> list[tuple[float, float, float]]:
        if not all(math.isfinite(c) for p in v for c in p):
            raise ValueError(f"artifacts_mm must be finite positions, got {v}")
        return v

    @model_validator(mode="after")
    def _turns_match(self) -> CalibrationConfig:
        turns = self.artifact_turns_deg
        if turns is not None:
            if len(turns) != len(self.artifacts_mm):
                raise ValueError(
                    f"artifact_turns_deg has {len(turns)} values for {len(self.artifacts_mm)} artifacts_mm"
                )
            if not all(math.isfinite(t) for t in turns):
                raise ValueError(f"artifact_turns_deg must be finite, got {turns}")
        normals = self.artifact_normals
        if normals is not None:
            if len(normals) != len(self.artifacts_mm):
                raise ValueError(
                    f"artifact_normals has {len(normals)} vectors for {len(self.artifacts_mm)} artifacts_mm"
                )
            for n in normals:
                norm = math.sqrt(sum(c * c for c in n))
                if not math.isfinite(norm) or norm < 1e-9 or n[2] / norm < 0.5:
                    raise ValueError(
                        f"artifact_normals must be upward vectors within 60 deg of the base's +z, got {n}"
                    )
        names = self.artifact_names
        if names is not None:
            if len(names) != len(self.artifacts_mm):
                raise ValueError(
                    f"artifact_names has {len(names)} names for {len(self.artifacts_mm)} artifacts_mm"
                )
            if len(set(names)) != len(names) or not all(n.strip() for n in names):
                raise ValueError(f"artifact_names must be distinct and not blank, got {names}")
        return self

    def names(self) -> list[str]:
        """Each artifact's name: ``artifact_names``, else ``1``, ``2``, ..."""
        return list(self.artifact_names or [str(k + 1) for k in range(len(self.artifacts_mm))])


class StationConfig(BaseModel):
    """A station configuration file (TOML), e.g.::

        name = "a465-lab-1"
        data_dir = "/srv/station-data"

        [robot]
        driver = "crs_a465"
        options = { port = "/dev/ttyS0" }
        safety = { max_step_deg = 20, table_z_mm = 0, min_camera_height_mm = 40 }
        reference_joints_deg = [0, 30, 60, 0, 90, 0]

        [camera]
        driver = "aravis"
        options = { camera_id = "Basler-12345" }
        camera_model = "camera.json"

        [table]
        driver = "manual"
        options = { x_travel_in = [0, 1], y_travel_in = [0, 1], origin_in = [0.5, 0.5] }

        [distance_sensor]
        driver = "keyence_il"
        options = { port = "/dev/ttyUSB0", head = { model = "IL-065" } }
        mount = { translation_mm = [30, 0, 0], rotation_deg = [0, 0, 0] }

        [measure]
        mode = "precise"

        [compute]
        cluster = "tcp://10.0.0.5:8786"

    Relative paths are taken from the file's folder.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field("station", min_length=1)
    data_dir: Path | None = None
    database: str | None = Field(None, description="SQLAlchemy URL; default SQLite in the data directory")
    robot: RobotConfig | None = None
    camera: CameraConfig
    table: TableConfig | None = None
    distance_sensor: DistanceSensorConfig | None = None
    measure: dict[str, Any] = Field(default_factory=dict, description="measurement parameters (--set)")
    scale_calibration: Path | None = Field(None, description="a scale calibration JSON file")
    api: ApiConfig = Field(default_factory=ApiConfig, description="the service's access control")
    compute: ComputeConfig = Field(
        default_factory=ComputeConfig, description="where offline sessions measure"
    )
    calibration: CalibrationConfig | None = Field(None, description="the kinematic calibration's cell")

    @model_validator(mode="after")
    def _one_camera_mount(self) -> StationConfig:
        try:
            self.camera_mount()
        except MountConflictError as exc:
            raise ValueError(str(exc)) from None
        return self

    def snapshot(self) -> dict[str, Any]:
        """JSON-ready copy for the record, with anything that looks like a secret redacted."""
        return redact(self.model_dump(mode="json"))

    def camera_mount(self) -> CameraMount:
        """The camera's mounting on the flange (``[camera] mount``, else the old ``[robot]
        safety.camera_offset_mm``): the nominal camera frame of jogs, teaching and calibration."""
        return camera_mount_of(self.model_dump(mode="json"))

    def camera_frame(self, what: str) -> CameraMount:
        """``camera_mount()`` for ``what``, which moves in the camera's frame; ConfigurationError when no
        mounting is given (the default, 100 mm straight out, would put such moves off by the difference)."""
        if self.camera.mount is None and (
            self.robot is None or LEGACY_CAMERA_OFFSET_KEY not in self.robot.safety
        ):
            raise ConfigurationError(
                f"{what} needs the camera's mounting on the flange: add [camera] mount = {{ translation_mm ="
                " [x, y, z], rotation_deg = [rx, ry, rz] }} to the configuration, read off the bracket's"
                " drawing (README: Bring-up, step 1)"
            )
        return self.camera_mount()

    def robot_latch_file(self) -> Path | None:
        """Where the robot's stop latch is kept across processes: ``robot-stop-latch.json`` in the data
        directory (``data_dir``, else ``$STATION_DATA``); ``None`` when neither is set (then the latch
        lives only as long as the driver object)."""
        base = self.data_dir if self.data_dir is not None else os.environ.get("STATION_DATA")
        return None if not base else Path(base) / ROBOT_LATCH_FILE

    def robot_safety(self) -> dict[str, Any]:
        """The robot driver's safety fields: ``[robot] safety`` with the camera's lens front
        (``camera_offset_mm``) and the carried bodies (the camera's and the distance sensor head's, in the
        flange frame) from the mounts. Empty without a robot."""
        if self.robot is None:
            return {}
        sensor = self.distance_sensor.mount if self.distance_sensor is not None else None
        return robot_safety_fields(self.robot.safety, self.camera_mount(), sensor)


def load_config(path: str | Path) -> StationConfig:
    """Read and validate a station configuration file; ConfigurationError says what is wrong and where."""
    p = Path(path)
    try:
        with p.open("rb") as f:
            raw = tomllib.load(f)
    except FileNotFoundError as exc:
        raise ConfigurationError(f"{p}: no such configuration file") from exc
    except OSError as exc:
        raise ConfigurationError(f"{p}: cannot read: {exc.strerror or exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigurationError(f"{p}: not valid TOML: {exc}") from exc
    try:
        config = StationConfig.model_validate(raw)
    except ValidationError as exc:
        problems = describe(exc, "(top level)")
        raise ConfigurationError(f"{p}: {problems}") from exc
    base = p.resolve().parent
    updates: dict[str, Any] = {}
    if config.data_dir is not None and not config.data_dir.is_absolute():
        updates["data_dir"] = base / config.data_dir
    if config.scale_calibration is not None and not config.scale_calibration.is_absolute():
        updates["scale_calibration"] = base / config.scale_calibration
    if config.camera.camera_model is not None and not config.camera.camera_model.is_absolute():
        updates["camera"] = config.camera.model_copy(
            update={"camera_model": base / config.camera.camera_model}
        )
    return config.model_copy(update=updates) if updates else config


# --------------------------------------------------------------------------- devices for a session


@dataclass
class StationDevices:
    """Everything a session drives, built but not connected (the runner connects and closes them).

    ``owned`` are further things to close after the devices (a simulated world's twins, prompt
    clients), last first. ``truth`` is for tests and benchmarks only (a simulated station's world);
    the runner and plans never read it.
    """

    config: StationConfig
    camera: Camera
    broker: PromptBroker
    robot: Robot | None = None
    table: XYTable | None = None
    distance_sensor: DistanceSensor | None = None
    owned: list[Any] = field(default_factory=list)
    truth: Any = None
    robot_options: dict[str, Any] = field(default_factory=dict)
    """The options the robot was built with, its safety fields aside (``rebuild_robot``)."""
    opened_id: str = field(default_factory=lambda: uuid.uuid4().hex)
    """This opening of the devices: what the station confirmed since holds only for it
    (``station.table_content``)."""

    @property
    def reference_joints_deg(self) -> tuple[float, ...] | None:
        return None if self.config.robot is None else tuple(self.config.robot.reference_joints_deg)

    @property
    def distance_sensor_mount(self) -> npt.NDArray[np.float64] | None:
        """4x4 pose of the distance sensor in the camera frame (``None`` without a sensor)."""
        cfg = self.config.distance_sensor
        return None if cfg is None or self.distance_sensor is None else cfg.mount.matrix()

    def rebuild_robot(self) -> None:
        """The robot built again (same driver and options, closed, not latched: its latch is in its file)
        with the configuration's safety fields as they are now: a taught mount moved a carried body."""
        if self.config.robot is None or self.robot is None:
            return
        self.robot = build(
            "robot", self.config.robot.driver, **self.robot_options, safety=self.config.robot_safety()
        )

    def identities(self) -> dict[str, dict[str, str | None]]:
        """Each device's identity, as recorded with a session."""
        out: dict[str, dict[str, str | None]] = {"camera": asdict(self.camera.identity())}
        if self.robot is not None:
            out["robot"] = asdict(self.robot.identity())
        if self.table is not None:
            out["table"] = asdict(self.table.identity())
        if self.distance_sensor is not None:
            out["distance_sensor"] = asdict(self.distance_sensor.identity())
        return out

    def close_owned(self) -> None:
        for thing in reversed(self.owned):
            try:
                thing.close()
            except Exception:
                log.exception("closing %r failed", thing)


def open_station(config: StationConfig, *, broker: PromptBroker | None = None) -> StationDevices:
    """Build (not connect) the devices a configuration names."""
    broker = broker or PromptBroker()
    camera: Camera = build("camera", config.camera.driver, **config.camera.options)
    robot: Robot | None = None
    options: dict[str, Any] = {}
    if config.robot is not None:
        options = dict(config.robot.options)
        latch = config.robot_latch_file()
        if latch is not None:
            options.setdefault("latch_file", str(latch))
        robot = build("robot", config.robot.driver, **options, safety=config.robot_safety())
    table: XYTable | None = None
    if config.table is not None:
        table = build("table", config.table.driver, broker=broker, **config.table.options)
    sensor: DistanceSensor | None = None
    if config.distance_sensor is not None:
        sensor = build("distance_sensor", config.distance_sensor.driver, **config.distance_sensor.options)
    return StationDevices(
        config=config,
        camera=camera,
        broker=broker,
        robot=robot,
        table=table,
        distance_sensor=sensor,
        robot_options=options,
    )


def open_sim_station(**options: Any) -> StationDevices:
    """The whole simulated station (controller twin on its pty with the real driver, sim camera, manual
    table answered by the simulated operator), built by the ``station.sim`` entry point of ``sim``."""
    devices: StationDevices = build("station", "sim", **options)
    return devices
