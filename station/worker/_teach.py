"""Jogging and teaching in the worker, between sessions, in one connection each (connect, act, close), as
``_arm`` moves the arm to its reference pose: the service's ``POST /station/robot/jog`` and
``POST /station/teach/...``.

A jog or a teach never clears a latched stop: it asks the robot first (``clear_stop`` releases nothing
and raises ``StopLatchedError`` while a stop is latched) and nothing moves. Every motion is checked by the
robot before it is sent (limits, step, keep-out along the path, the speed cap: ``station.jog``).

A teach writes the station's configuration file (``station.teach.update_config``: comments kept, the
old file backed up) and then applies the taught values to the configuration the worker's devices use
(:func:`with_taught`), so that the next session, jog or ``to-reference`` uses them at once; a taught
sensor mount also moves the sensor head's body in the robot's keep-out checks (the robot is built again
with the new safety fields). A simulated
station served with a configuration file (``ServiceSettings(sim=True, config=F)``) starts with that
file's taught values in place of the ones the simulator computes from its truth (:func:`with_taught`
again): what a lab has before it teaches its cell.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

from station.config import StationConfig, StationDevices
from station.devices import Robot
from station.jog import JOG_SPEED_PCT, JogError, jog
from station.kinematics import Kinematics
from station.record import station_lock
from station.worker._common import NotAvailableError, WorkerSpec

__all__ = ["TEACH_WHATS", "ArmTasks", "jog_arm", "teach_on", "with_taught"]

log = logging.getLogger(__name__)

TEACH_WHATS = ("reference", "artifact", "sensor-mount")
"""What can be taught (``station teach``'s and the API's names)."""


def with_taught(config: StationConfig, taught: StationConfig) -> StationConfig:
    """``config`` with the taught values of ``taught`` (the configuration file as written): the reference
    pose, ``[calibration]`` (artifacts, normals, turns, the optics' nominal values) and the distance
    sensor mount's translation and rotation, and the camera model (``[camera] camera_model``: what the
    camera's calibration writes and later sessions read). The devices' own settings (ports, drivers,
    safety, the sensor head's body) stay ``config``'s."""
    update: dict[str, Any] = {}
    if taught.camera.camera_model is not None:
        update["camera"] = config.camera.model_copy(update={"camera_model": taught.camera.camera_model})
    if config.robot is not None and taught.robot is not None:
        update["robot"] = config.robot.model_copy(
            update={"reference_joints_deg": taught.robot.reference_joints_deg}
        )
    if taught.calibration is not None:
        update["calibration"] = taught.calibration
    if config.distance_sensor is not None and taught.distance_sensor is not None:
        mount = config.distance_sensor.mount.model_copy(
            update={
                "translation_mm": taught.distance_sensor.mount.translation_mm,
                "rotation_deg": taught.distance_sensor.mount.rotation_deg,
            }
        )
        update["distance_sensor"] = config.distance_sensor.model_copy(update={"mount": mount})
    return config.model_copy(update=update)


def _jog_speed(config: StationConfig) -> float:
    safety = config.robot.safety if config.robot is not None else {}
    return float(safety.get("jog_speed_pct", JOG_SPEED_PCT))


def jog_arm(devices: StationDevices, request: Mapping[str, Any]) -> dict[str, Any]:
    """One jog (``{"mode": "joint", "joint", "delta_deg"}`` or ``{"mode": "camera", "axis", "delta"}``)
    at the configuration's jog speed (``[robot] safety.jog_speed_pct``, default 10 %, within the cap);
    what it did (``station.jog.JogResult.to_dict``). JogError, SpeedCapError, StopLatchedError: nothing
    moved."""
    robot: Robot | None = devices.robot
    if robot is None:
        raise JogError("this station has no robot to jog ([robot] in the configuration)")
    config = devices.config
    robot.connect()
    try:
        robot.clear_stop()  # releases nothing: raises while a stop is latched
        if request["mode"] == "joint":
            result = jog(
                robot,
                joint=int(request["joint"]),
                delta=float(request["delta_deg"]),
                speed_pct=_jog_speed(config),
            )
        else:
            nominal = Kinematics(tool=config.camera_frame("jogging the camera").matrix())
            result = jog(
                robot,
                camera_axis=str(request["axis"]),
                delta=float(request["delta"]),
                nominal=nominal,
                speed_pct=_jog_speed(config),
            )
    finally:
        robot.close()
    return result.to_dict()


def session_robot_identity(record: Any, session: Any) -> Mapping[str, Any] | None:
    """The robot's identity a session ran with: as it reported it once connected (the session's
    ``connected`` event), else as recorded when the session was created."""
    for event in record.events(session.id, limit=50):
        if event.type == "connected":
            robot = (event.data.get("devices") or {}).get("robot")
            if isinstance(robot, Mapping):
                return robot
    recorded = (session.identities or {}).get("robot")
    return recorded if isinstance(recorded, Mapping) else None


ModelOf = Callable[[StationDevices], Any]
"""What teaching reads through, resolved once the devices are connected (None: the nominal model)."""


def teach_on(
    devices: StationDevices,
    path: Path | None,
    what: str,
    name: str | None,
    model_of: ModelOf | None = None,
) -> dict[str, Any]:
    """Teach ``what`` (``reference``, ``artifact`` with its ``name``, ``sensor-mount``) from the devices
    (connected here, closed after), through ``model_of(devices)`` (a ``station.teach.TeachModel``; None:
    the nominal model), write it into the configuration at ``path`` (comments kept, the old file backed
    up) and apply it to ``devices.config``. ``{"what", "taught", "config", "backup", "changes"}``
    (``config`` and ``backup``: the files' names, in the configuration's folder; ``taught.model``: which
    model). TeachError (CalibrationRefusedError too), ConfigurationError, StopLatchedError,
    MotionRejectedError: nothing was written; NotAvailableError (nothing moved) without a configuration
    file (``path`` None)."""
    from station.teach import TeachError, rig_for, taught_values, update_config

    if what not in TEACH_WHATS:
        raise TeachError(f"teach one of {', '.join(TEACH_WHATS)}, not {what!r}")
    robot = devices.robot
    if robot is None:
        raise TeachError("teaching needs the robot ([robot] in the configuration)")
    opened = [d for d in (robot, devices.camera, devices.distance_sensor) if d is not None]
    try:
        for device in opened:
            device.connect()
        robot.clear_stop()  # releases nothing: raises while a stop is latched
        if path is None:
            raise NotAvailableError(
                "this service has no configuration file to teach into: start it with station serve"
                " --config station.toml (a simulated station's taught values come from its truth)"
            )
        model = model_of(devices) if model_of is not None else None
        taught, edit = taught_values(rig_for(devices, model=model), what, name)
        done = update_config(path, edit)
    finally:
        for device in reversed(opened):
            device.close()
    safety = devices.config.robot_safety()
    devices.config = with_taught(devices.config, done.config)
    if devices.config.robot_safety() != safety:  # a taught mount moved the sensor head the checks carry
        devices.rebuild_robot()
    return {
        "what": what,
        "taught": taught,
        "config": done.path.name,
        "backup": done.backup.name,
        "changes": list(done.changes),
    }


class ArmTasks:
    """The worker's jog and teach (``rpc_jog``, ``rpc_teach``), mixed into ``SessionHost``: each runs
    while no session runs and nothing else moves the arm, holding the station's lock, the arm marked as
    moving meanwhile (``_motion`` says how, to a refused caller)."""

    spec: WorkerSpec
    devices: Any
    record: Any
    _lock: threading.RLock
    _moving: bool
    _motion: str = "on its way to its reference pose"

    def _settle(self) -> None:  # pragma: no cover - SessionHost's
        raise NotImplementedError

    def _idle_robot(self, what: str) -> Any:  # pragma: no cover - SessionHost's
        raise NotImplementedError

    def _arm_task(self, motion: str, lock_name: str, fn: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        """``fn()`` while no session runs and nothing else moves the arm (ConflictError otherwise), holding
        the station's lock; the arm is ``motion`` meanwhile."""
        self._settle()
        with self._lock:
            if self._idle_robot("move it") is None:
                raise NotAvailableError("this station has no robot to move ([robot] in the configuration)")
            self._moving, self._motion = True, motion
        try:
            with station_lock(self.record.data_dir, lock_name):
                return fn()
        finally:
            with self._lock:
                self._moving = False

    def rpc_jog(self, request: Mapping[str, Any]) -> dict[str, Any]:
        """One jog (:func:`jog_arm`); JogError, SpeedCapError, StopLatchedError: nothing moved."""
        return self._arm_task("being jogged", "jog", lambda: jog_arm(self.devices, request))

    def _station_name(self) -> str:  # pragma: no cover - SessionHost's
        raise NotImplementedError

    def _calibrated_model(self, session_id: str) -> ModelOf:
        """The model of calibration session ``session_id`` (``station.teach.model_from_session``), checked
        against the robot once it is connected."""
        from station.record import RecordNotFoundError
        from station.teach import CalibrationSessionInvalidError, model_from_session

        def model_of(devices: StationDevices) -> Any:
            try:
                session = self.record.get_session(session_id)
            except RecordNotFoundError as exc:
                raise CalibrationSessionInvalidError(
                    f"no calibration session {session_id!r} on record ({exc}): run the arm's calibration"
                    " (station run calibration, or the page's Sessions panel) and name it"
                ) from exc
            robot = devices.robot
            return model_from_session(
                session,
                station=self._station_name(),
                robot_identity=None if robot is None else asdict(robot.identity()),
                session_identity=session_robot_identity(self.record, session),
                camera_mount=devices.config.camera_frame("teaching").matrix(),
            )

        return model_of

    def rpc_teach(
        self, what: str, name: str | None, calibration_session: str | None = None
    ) -> dict[str, Any]:
        """Teach ``what`` into the station's configuration file (:func:`teach_on`), through the calibrated
        arm of ``calibration_session`` when one is named; NotAvailableError when the service has no
        configuration file to write (said once the arm is free and its stop not latched: what to do
        first comes first)."""
        path = self.spec.config
        model_of = None if calibration_session is None else self._calibrated_model(calibration_session)
        done = self._arm_task(
            "being taught", "teach", lambda: teach_on(self.devices, path, what, name, model_of)
        )
        log.info("taught %s into %s (the old file is %s)", what, done["config"], done["backup"])
        return done
