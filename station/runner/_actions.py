"""The action executor: each action of a step run by the handler registered for its type (``HANDLERS``).

A handler takes the executor (the devices, the step's run so far, the abort signal) and the action, and
returns what it adds to the step's data. A new action type is one handler and one line in ``HANDLERS``.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from station.config import StationDevices
from station.devices import (
    DeviceError,
    DeviceProtocolError,
    DeviceTimeoutError,
    DistanceSensor,
    OutOfRangeError,
    SensorAlarmError,
)
from station.plans import (
    Align,
    AlignInput,
    AlignSkippedError,
    Capture,
    Compute,
    DeviceCheck,
    MoveAligned,
    MoveJoints,
    MoveOffset,
    MoveTable,
    PlanContext,
    PlanError,
    SetSpeed,
    Settle,
    Step,
)
from station.plans._ruler import capture_params
from station.runner._journal import Journal
from station.runner._states import AbortRequestedError, SessionError
from station.runner._store import Grabbed, StepRun
from station.vision import MeasurementError, MeasureParams, measure, measure_ruler


@dataclass
class ActionExecutor:
    """Runs a step's actions on the station's devices, in the runner's thread (the devices' only user).

    ``aborted()`` says whether an abort was asked; ``wait_for_abort(seconds)`` waits that long unless an
    abort comes first (and says whether it came); ``positions()`` is the plan's step count (the
    operator's prompt says "position n of m"); ``run_meta()`` what each capture and step records of the
    session's run.
    """

    devices: StationDevices | None
    ctx: PlanContext
    measure_params: MeasureParams
    journal: Journal
    aborted: Callable[[], bool]
    wait_for_abort: Callable[[float], bool]
    positions: Callable[[], int]
    run_meta: Callable[[], dict[str, int]]
    prompt_timeout_s: float | None = None
    current: StepRun | None = None

    def run(self, run: StepRun, before_action: Callable[[], None]) -> None:
        """Every action of ``run.step`` in order (``before_action()`` before each: the store's errors);
        an align that cannot be done skips the rest of the step, with a warning."""
        self.current = run
        for action in run.step.actions:
            if self.aborted():
                raise AbortRequestedError()
            before_action()
            handler = HANDLERS.get(type(action))
            if handler is None:
                raise PlanError(f"unknown action {action!r}")
            try:
                run.data.update(handler(self, action))
            except AlignSkippedError as skipped:
                run.data["skipped"] = str(skipped)
                self.journal.emit("warning", {"message": f"{run.step.name}: {skipped}"})
                break

    def _run(self) -> StepRun:
        assert self.current is not None
        return self.current

    def _devices(self) -> StationDevices:
        assert self.devices is not None  # a plan with device actions runs with devices (pre-flight)
        return self.devices

    def _pause_unless_aborted(self, seconds: float) -> None:
        if self.wait_for_abort(seconds):
            raise AbortRequestedError()

    # ------------------------------------------------------------------ the handlers

    def compute(self, action: Compute) -> dict[str, Any]:
        return action.run(self.ctx)

    def device_check(self, action: DeviceCheck) -> dict[str, Any]:
        return action.run(self._devices())

    def set_speed(self, action: SetSpeed) -> dict[str, Any]:
        require(self._devices().robot, "robot").set_speed(action.percent)
        return {}

    def move_joints(self, action: MoveJoints) -> dict[str, Any]:
        require(self._devices().robot, "robot").move_joints(action.target_deg)
        self._run().offset_base = tuple(action.target_deg)
        return {}

    def move_offset(self, action: MoveOffset) -> dict[str, Any]:
        robot = require(self._devices().robot, "robot")
        base = self._run().offset_base
        if base is None:
            raise PlanError("a MoveOffset needs a MoveJoints or an Align before it in its step")
        target = tuple(b + o for b, o in zip(base, action.offset_deg, strict=True))
        robot.check_move(target)  # from where the arm is: the aligned pose differs from the planned one
        robot.move_joints(target)
        return {}

    def move_table(self, action: MoveTable) -> dict[str, Any]:
        devices = self._devices()
        table = require(devices.table, "table")
        step = self._run().step
        # the operator's prompt says which position of how many, whether this is the overshoot, and
        # whether it is a resume's check of the last confirmed position
        at = step.meta.get("position")  # a resume's check repeats an earlier position
        details: dict[str, str | float] = {
            "position": (at if isinstance(at, int) else step.index) + 1,
            "positions": self.positions(),
            "move": "overshoot" if action.overshoot else "position",
        }
        if step.meta.get("role") == "resume_check":
            details["purpose"] = "resume_check"
        with devices.broker.context(**details):
            pos = table.move_to(action.x_mm, action.y_mm, timeout_s=self.prompt_timeout_s)
        return {} if action.overshoot else {"table_confirmed_mm": [pos.x_mm, pos.y_mm]}

    def settle(self, action: Settle) -> dict[str, Any]:
        self._pause_unless_aborted(action.seconds)
        return {}

    def capture(self, action: Capture) -> dict[str, Any]:
        self._run().grabbed.append(self.grab(action))
        return {}

    def align(self, action: Align) -> dict[str, Any]:
        """Measure, correct within bounds, check, move; repeat (see :class:`~station.plans.Align`)."""
        robot = require(self._devices().robot, "robot")
        run = self._run()
        planned = action.planned_deg
        corrections: list[dict[str, Any]] = []
        for iteration in range(action.max_iterations + 1):
            grabbed = self.grab(Capture(1, {**action.meta, "iteration": iteration}))
            run.grabbed.append(grabbed)  # stored like any capture: nothing captured is lost
            meta = grabbed.meta
            z_mm = meta.get("z_mm")  # the distance sensor's reading with the frame (None without one)
            image = grabbed.frames[0].image
            center: tuple[float, float] | None = None
            ruler: tuple[float, float] | None = None
            error: str | None = None
            params = capture_params(meta, self.measure_params, image.shape)
            try:
                if isinstance(params, MeasureParams):
                    m = measure(image, params)
                    center = (float(m.center_px[0]), float(m.center_px[1]))
                else:  # a ruler's view (station.plans._ruler): where along and across it
                    r = measure_ruler(image, params)
                    ruler = (float(r.position_mm), float(r.offset_mm))
            except MeasurementError as exc:
                error = exc.message
            joints = tuple(float(a) for a in meta.get("joints_deg", planned))
            size = (int(image.shape[1]), int(image.shape[0]))
            seen = AlignInput(joints, center, z_mm, size, error, ruler_st_mm=ruler)
            correction = action.correct(seen)
            if correction is None:
                # offsets start from where the controller was commanded (its own 0.001 deg grid)
                commanded = meta.get("commanded_joints_deg", joints)
                run.offset_base = tuple(float(a) for a in commanded)
                done: dict[str, Any] = {"aligned_joints_deg": list(joints), "corrections": corrections}
                if action.view:  # a named view: kept for the step's MoveAligned
                    done["aligned_views"] = {**run.data.get("aligned_views", {}), action.view: list(joints)}
                return done
            if iteration == action.max_iterations:
                break
            worst = max(abs(t - p) for t, p in zip(correction.target_deg, planned, strict=True))
            if correction.translation_mm > action.max_translation_mm or worst > action.max_joint_deg:
                raise AlignSkippedError(
                    f"the correction ({correction.translation_mm:.3f} mm, {worst:.3f} deg from the planned"
                    f" pose) exceeds its bounds ({action.max_translation_mm} mm, {action.max_joint_deg} deg):"
                    " the artifact is not where the cell says; configuration skipped"
                )
            robot.check_move(correction.target_deg)
            robot.move_joints(correction.target_deg)
            corrections.append(
                {"iteration": iteration, "translation_mm": correction.translation_mm, "z_mm": z_mm}
            )
            if action.settle_s:
                self._pause_unless_aborted(action.settle_s)
        raise AlignSkippedError(
            f"not aligned after {action.max_iterations} corrections: configuration skipped"
        )

    def move_aligned(self, action: MoveAligned) -> dict[str, Any]:
        """To ``action.target`` of where the step's Align ended, within its bound of the planned joints."""
        robot = require(self._devices().robot, "robot")
        run = self._run()
        views = run.data.get("aligned_views")
        if not views:
            raise PlanError("a MoveAligned needs a named Align (view) that succeeded before it in its step")
        target, record = action.target({k: tuple(float(a) for a in v) for k, v in views.items()})
        worst = max(abs(t - p) for t, p in zip(target, action.planned_deg, strict=True))
        if worst > action.max_joint_deg:
            raise AlignSkippedError(
                f"the re-centred pose is {worst:.3f} deg from the planned one (bound {action.max_joint_deg}"
                " deg): the artifact is not where the cell says; the step's remaining frames skipped"
            )
        robot.check_move(target)
        robot.move_joints(target)
        run.offset_base = tuple(target)
        return {"recentred": [*run.data.get("recentred", []), dict(record)]}

    # ------------------------------------------------------------------ grabbing

    def grab(self, action: Capture) -> Grabbed:
        """Where the arm is (and the table, and the distance), then the frames."""
        devices = self._devices()
        run = self._run()
        meta: dict[str, Any] = {**action.meta, **self.run_meta()}
        if devices.robot is not None:
            pos = devices.robot.where()
            meta["joints_deg"] = list(pos.joints_deg)
            meta["commanded_joints_deg"] = list(pos.commanded_joints_deg)
        if devices.table is not None:
            with contextlib.suppress(DeviceError):
                p = devices.table.position()
                meta["table_mm"] = [p.x_mm, p.y_mm]
        if devices.distance_sensor is not None:
            # read just before the frames: a lost link fails the step before anything is grabbed
            z_mm, z_error = self._read_z(devices.distance_sensor)
            meta["z_mm"] = z_mm
            if z_error is not None:
                meta["z_error"] = z_error
        first = run.next_frame
        frames = devices.camera.grab_many(action.frames)
        run.next_frame += len(frames)
        return Grabbed(frames, meta, first)

    def _read_z(self, sensor: DistanceSensor) -> tuple[float | None, str | None]:
        """The distance sensor's reading for a capture: (mm, None), or (None, why) when it has no valid
        distance (out of range, alarm: the capture goes on, its z is missing). A garbled or lost reply
        is read once more; a second failure, or a lost link, fails the step."""
        for attempt in (1, 2):
            try:
                return sensor.read_mm(), None
            except (OutOfRangeError, SensorAlarmError) as exc:
                self.journal.emit("warning", {"message": f"no z with this capture: {exc}"})
                return None, str(exc)
            except (DeviceProtocolError, DeviceTimeoutError) as exc:
                if attempt == 2:
                    raise
                self.journal.emit("warning", {"message": f"distance sensor: {exc}; reading again"})
        raise AssertionError("unreachable")


Handler = Callable[[ActionExecutor, Any], dict[str, Any]]

HANDLERS: dict[type, Handler] = {
    Compute: ActionExecutor.compute,
    DeviceCheck: ActionExecutor.device_check,
    SetSpeed: ActionExecutor.set_speed,
    MoveJoints: ActionExecutor.move_joints,
    MoveOffset: ActionExecutor.move_offset,
    MoveTable: ActionExecutor.move_table,
    Settle: ActionExecutor.settle,
    Capture: ActionExecutor.capture,
    Align: ActionExecutor.align,
    MoveAligned: ActionExecutor.move_aligned,
}
"""The action executor's registry: each action type's handler."""


def require(device: Any, name: str) -> Any:
    """``device``, or the session error that says the configuration lacks it."""
    if device is None:
        raise SessionError(f"this step needs the {name}, which the station configuration does not have")
    return device


def step_moves(step: Step) -> bool:
    """Whether the step moves the arm or the table."""
    return any(isinstance(a, MoveJoints | MoveTable | MoveOffset | Align | MoveAligned) for a in step.actions)
