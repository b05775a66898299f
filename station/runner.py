"""The session runner: runs one plan over the station's devices, records everything, obeys the operator.

States (``RunnerState``)::

    idle -> running <-> awaiting_operator
            running -> pausing -> paused -> running
            running | paused | awaiting_operator -> stopping -> stopped
            any active state -> aborting -> aborted
            any active state -> failed | succeeded
    a session whose process died shows ``interrupted`` (found when the next runner takes the lock)

* Every session (and every resume) starts at its plan's reference pose: when the arm is elsewhere, its
  first step is the arm's route there from where it is commanded (``station.arm_route``), checked in
  pre-flight with everything else; a plan that never moves the arm (validation) is refused instead.
* **Pause** takes effect at the next safe point (between steps); **resume** continues.
* **Stop** finishes the step in progress, returns the arm to the reference pose (along the same route),
  closes the devices.
* **Abort** stops the robot now through its latched stop, cancels the open operator prompt, and moves
  nothing more; the latch stays set on the driver.
* A device error fails the session: the robot is stopped, its position read again and recorded, and
  everything captured until then stays in the record.
* One session at a time per station (data directory), across processes: a ``station_lock`` that a dead
  owner's lock does not block. After a crash, ``resume`` continues after the last completed step, or
  from where the plan's resume rule says (``resume_from``: repeatability reruns the interrupted test).
* Gates: a result that fails one of its ``fail`` checks (``results.checks``) ends the session ``failed``
  with their messages, its results kept; a plan's ``check_progress`` stops it at once. A validation that
  succeeded writes the station's scale calibration before its state says so.

Every capture is stored (lossless, fsynced) before it is measured, and measured from the stored file, so
re-analysis of the record reproduces the live results bit for bit. Events (state changes, steps, images,
measurements, prompts, warnings, errors) are persisted with a per-session sequence number and a
station-wide id, and passed to the runner's listeners (``station serve``'s worker forwards them to the
API's streams, ``station.worker``).
"""

from __future__ import annotations

import contextlib
import enum
import logging
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from station import __version__, scale_calibration
from station.arm_route import TO_REFERENCE_HINT, describe_offset, go_to_reference, max_step_of, plan_route
from station.batch import measure_file
from station.compute import ComputeError, MeasureBackend
from station.config import StationDevices
from station.devices import (
    DeviceError,
    DeviceProtocolError,
    DeviceTimeoutError,
    DistanceSensor,
    Frame,
    MotionRejectedError,
    MotionStoppedError,
    OperatorCancelledError,
    OutOfRangeError,
    SensorAlarmError,
    StopLatchedError,
)
from station.kinds import get_plan
from station.plans import (
    Action,
    Align,
    AlignInput,
    AlignSkippedError,
    Capture,
    CaptureResult,
    Compute,
    DeviceCheck,
    MoveJoints,
    MoveOffset,
    MoveTable,
    Plan,
    PlanContext,
    PlanError,
    SetSpeed,
    Settle,
    Step,
    station_cell,
)
from station.plans._gates import verdict
from station.prompts import PromptError, PromptEvent
from station.record import EventRow, Record, RecordError, SessionRow, station_lock
from station.scale_preflight import ScalePreflight
from station.selftest_status import attach_to_session, robot_identity
from station.vision import MeasurementError, MeasureParams, measure

log = logging.getLogger(__name__)

PRELUDE_BASE = 1_000_000
"""Step indices of resume preludes start here (plan steps are numbered from 0)."""
FRAMES_PER_ATTEMPT = 1000
"""A step's frames are numbered from attempt x FRAMES_PER_ATTEMPT (plans capture at most 100 per step)."""
EARLY_FAILURE_CAPTURES = 3
"""A session whose first this-many captures all fail to measure stops: something is misconfigured."""


class RunnerState(enum.StrEnum):
    IDLE = "idle"
    RUNNING = "running"
    PAUSING = "pausing"
    PAUSED = "paused"
    AWAITING_OPERATOR = "awaiting_operator"
    STOPPING = "stopping"
    STOPPED = "stopped"
    ABORTING = "aborting"
    ABORTED = "aborted"
    FAILED = "failed"
    SUCCEEDED = "succeeded"
    INTERRUPTED = "interrupted"


FINAL_STATES = frozenset(
    {
        RunnerState.STOPPED,
        RunnerState.ABORTED,
        RunnerState.FAILED,
        RunnerState.SUCCEEDED,
        RunnerState.INTERRUPTED,
    }
)
ACTIVE_STATES = frozenset(
    {
        RunnerState.RUNNING,
        RunnerState.PAUSING,
        RunnerState.PAUSED,
        RunnerState.AWAITING_OPERATOR,
        RunnerState.STOPPING,
        RunnerState.ABORTING,
    }
)


class SessionError(RuntimeError):
    """A session cannot be started, resumed or controlled (the message says why and what to do)."""


class PreflightError(SessionError):
    """Pre-flight found problems; nothing moved. ``problems`` lists every one."""

    def __init__(self, problems: Sequence[str]) -> None:
        super().__init__(
            f"pre-flight found {len(problems)} problem(s); nothing moved:\n  - " + "\n  - ".join(problems)
        )
        self.problems = list(problems)


class _AbortRequestedError(Exception):
    """Raised in the runner thread when an abort was requested."""


class _StopRequestedError(Exception):
    """Raised at a safe point when a stop was requested."""


class Progress(BaseModel):
    """A session's progress: steps done of the plan's total, and the estimated time left (s); the API's
    ``progress`` and the ``step_finished`` event's."""

    model_config = ConfigDict(frozen=True)

    done: int = Field(ge=0)
    total: int = Field(ge=0)
    eta_s: float | None = None

    def to_json(self) -> dict[str, Any]:
        return self.model_dump()


def software_info() -> dict[str, str]:
    import platform

    import cv2
    import numpy as np

    return {
        "station": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "opencv": cv2.__version__,
        "host": socket.gethostname(),
    }


def reconcile(record: Record) -> list[str]:
    """Mark sessions left in an active state by a dead process as ``interrupted``; call with the station
    lock held (no live runner can own them then). Returns the ids marked."""
    marked = []
    for s in record.list_sessions():
        if s.state in ACTIVE_STATES:
            record.set_state(s.id, RunnerState.INTERRUPTED, error=s.error)
            record.add_event(s.id, "state", {"state": RunnerState.INTERRUPTED, "was": s.state})
            marked.append(s.id)
    return marked


class SessionRunner:
    """Runs one plan: create (or resume) a session in the record, then ``run()`` (blocking) or
    ``start()`` (a thread); control with ``pause``/``resume``/``stop``/``abort`` from any thread.

    Parameters
    ----------
    record
        Where everything goes.
    plan, params
        The plan and its validated parameters.
    devices
        The station's devices (built, not connected); ``None`` for offline plans.
    measure_params
        Measurement parameters of this session.
    resume_session
        An interrupted (or stopped, failed, aborted) session to continue; ``plan`` and ``params`` must
        be its own.
    jobs, compute
        Where offline plans measure: ``compute`` (a backend of ``station.compute``, owned by the
        caller, which closes it), else a local pool of ``jobs`` processes. A backend's failure (its
        cluster gone) fails the session, which can then be resumed.
    """

    def __init__(
        self,
        record: Record,
        plan: Plan,
        params: BaseModel,
        *,
        devices: StationDevices | None = None,
        measure_params: MeasureParams | None = None,
        scale_calibration: dict[str, Any] | None = None,
        resume_session: SessionRow | None = None,
        jobs: int = 1,
        compute: MeasureBackend | None = None,
        station: str = "default",
        config_snapshot: dict[str, Any] | None = None,
    ) -> None:
        missing = sorted(n for n in plan.needs if devices is None or getattr(devices, n, None) is None)
        if missing:
            raise SessionError(f"a {plan.name} session needs a {' and a '.join(missing)}; configure them")
        self.record = record
        self.plan = plan
        self.params = params
        self.devices = devices
        self.measure_params = measure_params or MeasureParams()
        self.scale_calibration = scale_calibration
        self.jobs = jobs
        self.compute = compute
        self._station = station
        self._config_snapshot = config_snapshot
        self._resume = resume_session
        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        self._state = RunnerState.IDLE
        self._pause = False
        self._stop = False
        self._abort = False
        self._listeners: list[Callable[[EventRow], None]] = []
        self._thread: threading.Thread | None = None
        self._done = 0
        self._total = 0
        self._t_steps: deque[float] = deque(maxlen=20)  # the latest step durations, for the ETA
        self._session_id: str | None = resume_session.id if resume_session else None
        self._captures = 0
        self._measured_ok = 0
        self._last_error: str | None = None
        self._stop_sent = threading.Event()  # abort's robot stop has been sent (or there was none)
        self._store_pool: ThreadPoolExecutor | None = None
        self._store_futures: list[Future[None]] = []
        self._offset_base: tuple[float, ...] | None = None  # where a step's MoveOffset offsets start
        self._frame_base = 0  # the current step attempt's first frame index
        self._frames_in_step = 0
        self._run = 0  # how many times this session was resumed: captures of a resumed run carry it
        self.error: str | None = None
        self.results: dict[str, Any] | None = None
        self._scale = ScalePreflight(devices, plan, self.measure_params, scale_calibration, self._event)

    # ------------------------------------------------------------------ observation

    @property
    def session_id(self) -> str | None:
        return self._session_id

    @property
    def state(self) -> RunnerState:
        return self._state

    def progress(self) -> Progress:
        with self._lock:
            done, total = self._done, self._total
            eta = None
            if self._t_steps and total:
                per = sum(self._t_steps) / len(self._t_steps)
                eta = round(per * (total - done), 1)
            return Progress.model_construct(done=done, total=total, eta_s=eta)

    def subscribe(self, listener: Callable[[EventRow], None]) -> Callable[[], None]:
        """Call ``listener(event)`` for every event of this session (from the runner's thread)."""
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    # ------------------------------------------------------------------ control

    def pause(self) -> None:
        """Pause at the next safe point (between steps)."""
        with self._lock:
            if self._state in FINAL_STATES or self._stop or self._abort:
                raise SessionError(f"cannot pause a session that is {self._state}")
            self._pause = True
            if self._state is RunnerState.RUNNING:
                self._set_state(RunnerState.PAUSING)
            self._cond.notify_all()

    def resume(self) -> None:
        """Continue after a pause."""
        with self._lock:
            if self._state not in (RunnerState.PAUSED, RunnerState.PAUSING):
                raise SessionError(f"cannot resume a session that is {self._state}; only a paused one")
            self._pause = False
            if self._state is RunnerState.PAUSING:
                self._set_state(RunnerState.RUNNING)
            self._cond.notify_all()

    def stop(self) -> None:
        """Finish the step, return the arm to the reference pose, close the devices: ``stopped``."""
        with self._lock:
            if self._state in FINAL_STATES or self._abort:
                return
            self._stop = True
            if self._state is not RunnerState.IDLE:
                self._set_state(RunnerState.STOPPING)
            self._cond.notify_all()

    def abort(self, reason: str = "aborted by the operator") -> None:
        """Stop the robot now (latched), cancel the open prompt, move nothing more: ``aborted``.

        The robot's stop never waits for the runner's lock: when the lock is busy (a listener of the
        runner's events is slow), the stop is sent first and the state follows once the lock is free.
        """
        if self._state in FINAL_STATES or self._abort:
            return
        locked = self._lock.acquire(timeout=0.2)
        try:
            if self._state in FINAL_STATES or self._abort:
                return
            self._abort = True
            self.error = self.error or reason
            if locked:
                self._enter_aborting()
        finally:
            if locked:
                self._lock.release()
        devices = self.devices
        if devices is not None and devices.robot is not None:
            try:
                devices.robot.stop()
            except Exception as exc:  # noqa: BLE001 - the prompt must still be cancelled
                log.error("abort: robot stop failed: %s (use the E-stop)", exc)
                self._event("error", {"message": f"robot stop failed during abort: {exc}; use the E-stop"})
        self._stop_sent.set()
        if not locked:
            with self._lock:
                self._enter_aborting()
        if devices is not None:
            prompt = devices.broker.current(pending=True)
            if prompt is not None:
                with contextlib.suppress(PromptError):
                    devices.broker.cancel(prompt.id, reason=reason, by="runner")

    def _enter_aborting(self) -> None:
        """With the lock held: ``aborting`` unless the session has not started or has already ended."""
        if self._state is not RunnerState.IDLE and self._state not in FINAL_STATES:
            self._set_state(RunnerState.ABORTING)
        self._cond.notify_all()

    # ------------------------------------------------------------------ running

    def create(self) -> SessionRow:
        """Create the session in the record (state ``idle``) without running it."""
        if self._session_id is not None:
            return self.record.get_session(self._session_id)
        identities = self.devices.identities() if self.devices is not None else {}
        snapshot = self._config_snapshot
        if snapshot is None and self.devices is not None:
            snapshot = self.devices.config.snapshot()
        row = self.record.create_session(
            self.plan.name,
            params={
                "plan": self.params.model_dump(mode="json"),
                "measure": self.measure_params.model_dump(mode="json"),
                "scale_calibration": self.scale_calibration,
            },
            config=snapshot or {},
            identities=identities,
            software=software_info(),
            station=self._station,
        )
        self._session_id = row.id
        return row

    def start(self) -> threading.Thread:
        """Run in a new thread; returns it (join it, or watch ``state``)."""
        thread = threading.Thread(target=self._run_quietly, name=f"runner-{self.plan.name}", daemon=True)
        self._thread = thread
        thread.start()
        return thread

    def _run_quietly(self) -> None:
        try:
            self.run()
        except Exception:
            log.exception("session runner ended with an error")

    def run(self) -> RunnerState:
        """Run the session to its end; returns the final state. Raises ``SessionLockError`` when another
        session holds the station (nothing is created or moved then)."""
        data_dir = Path(self.record.data_dir)
        with station_lock(data_dir, self._session_id or "new") as held:
            reconcile(self.record)
            session = self.create()
            sid = session.id
            unsubscribe = None
            if self.devices is not None:
                unsubscribe = self.devices.broker.subscribe(self._on_prompt)
            try:
                final = self._run_session(sid)
            except BaseException:  # Ctrl-C, SystemExit, an error before it ran: recorded (the arm stopped)
                held.release()
                self._finish(sid, RunnerState.ABORTED if self._abort else RunnerState.FAILED)
                raise
            finally:
                if unsubscribe is not None:
                    unsubscribe()
            # the station is free before anyone can see the outcome: whoever sees it may start the next
            # session at once (that one waits for this final state to be recorded before it reconciles)
            held.release()
            self._finish(sid, final)
            return final

    def _run_session(self, sid: str) -> RunnerState:
        ctx = self._context(sid)
        final = RunnerState.FAILED
        with self._lock:
            if self._abort:
                return RunnerState.ABORTED
            self._set_state(RunnerState.STOPPING if self._stop else RunnerState.RUNNING)
        try:
            with contextlib.ExitStack() as stack:
                stack.callback(self._close_store)
                self._store_pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="runner-store")
                try:
                    steps, prelude = self._steps(ctx)
                    self._connect(stack)
                    route, problems = self._route(ctx, prelude)
                    self._preflight(route + prelude + steps, problems)
                    for step in route + prelude + steps:
                        self._safe_point()
                        self._run_step(sid, step, ctx)
                        self._check_progress(sid, ctx)
                    self._drain()
                    self._check_store()
                    final = RunnerState.SUCCEEDED
                except _StopRequestedError:
                    self._return_to_reference()
                    self._drain()
                    self._check_store()
                    final = RunnerState.STOPPED
                finally:
                    self._set_state_if_active(RunnerState.STOPPING if final is RunnerState.STOPPED else None)
            self._analyse(sid, ctx, keep_going=final is not RunnerState.SUCCEEDED)
            if final is RunnerState.SUCCEEDED and self.results is None:
                final = RunnerState.FAILED
            gates = verdict(self.results)
            if final is RunnerState.SUCCEEDED and gates is not None:
                # a result that fails a gate is kept and shown, marked failed: never a success
                final = RunnerState.FAILED
                self.error = gates
                self._event("error", {"message": gates, "type": "GateError"})
        except (_AbortRequestedError, MotionStoppedError, OperatorCancelledError) as exc:
            if self._abort:
                final = RunnerState.ABORTED
                self._reread_position("abort")
                self._analyse(sid, ctx, keep_going=True)
            else:
                final = RunnerState.FAILED
                self._fail(exc)
                self._analyse(sid, ctx, keep_going=True)
        except (DeviceError, RecordError, PlanError, SessionError, ComputeError, OSError, ValueError) as exc:
            final = RunnerState.ABORTED if self._abort else RunnerState.FAILED
            self._fail(exc)
            self._analyse(sid, ctx, keep_going=True)
        except BaseException as exc:  # KeyboardInterrupt, SystemExit: stop the arm; run() records it
            self._fail(exc)
            raise
        return final

    def _close_store(self) -> None:
        """Store what is still queued (nothing captured is lost), then end the store thread."""
        pool, self._store_pool = self._store_pool, None
        if pool is not None:
            pool.shutdown(wait=True)
        for f in self._store_futures:
            exc = f.exception()
            if exc is not None and str(exc) != self.error:
                log.error("storing a capture failed: %s", exc)

    def _finish(self, sid: str, final: RunnerState) -> None:
        if self.results is not None:
            self.record.set_results(sid, self.results)
        if final is RunnerState.SUCCEEDED:
            self._write_scale_calibration()  # before the state says succeeded: a client then finds it
        with self._lock:
            self._set_state(final)
        self.record.set_state(sid, final, error=None if final is RunnerState.SUCCEEDED else self.error)
        log.info("session %s %s", sid, final)

    def _write_scale_calibration(self) -> None:
        """A validation that passed every gate: its groove-width estimate becomes the station's scale
        calibration (the one it replaces stays in the history, ``station.scale_calibration``)."""
        cal = scale_calibration.from_validation(self.plan.name, RunnerState.SUCCEEDED, self.results)
        if cal is None:
            return
        try:
            entry = scale_calibration.write(self.record.data_dir, cal)
        except (scale_calibration.ScaleCalibrationError, OSError) as exc:
            self._event("warning", {"message": f"the scale calibration could not be written: {exc}"})
            return
        self._event("scale_calibration", {"version": entry.version, **cal.record()})

    def _fail(self, exc: BaseException) -> None:
        message = str(exc) or type(exc).__name__
        if self.error is None or not self._abort:
            self.error = message
        log.error("session failed: %s", message)
        self._event("error", {"message": message, "type": type(exc).__name__})
        robot = self.devices.robot if self.devices is not None else None
        if robot is not None and isinstance(exc, DeviceError | KeyboardInterrupt | SystemExit):
            with contextlib.suppress(Exception):
                robot.stop()
            self._reread_position("error")

    def _reread_position(self, why: str) -> None:
        robot = self.devices.robot if self.devices is not None else None
        if robot is None:
            return
        try:
            pos = robot.where()
        except Exception as exc:  # noqa: BLE001 - recorded; the operator must look at the arm
            self._event("warning", {"message": f"after the {why}, the position could not be read: {exc}"})
            return
        self._event("position", {"after": why, "joints_deg": list(pos.joints_deg)})

    def _analyse(self, sid: str, ctx: PlanContext, *, keep_going: bool) -> None:
        try:
            captures = self._capture_results(sid)
            self.results = self.plan.analyse(self.params, ctx, captures)
            self.results = attach_to_session(self.results, self.record, sid, robot_identity(self.devices))
        except (PlanError, ValueError, RecordError) as exc:
            if not keep_going:
                self.error = f"analysis failed: {exc}"
                self._event("error", {"message": self.error})
            else:
                self._event("warning", {"message": f"no results from the partial session: {exc}"})
            self.results = None

    def _capture_results(self, sid: str) -> list[CaptureResult]:
        source_of = getattr(self.plan, "source_session", None)
        source = self.record.get_session(source_of(self.params)).id if source_of is not None else sid
        return stored_captures(self.record, source, measured_in=sid)

    # ------------------------------------------------------------------ steps

    def _context(self, sid: str) -> PlanContext:
        devices = self.devices
        reference = devices.reference_joints_deg if devices is not None else None
        return PlanContext(
            measure_params=self.measure_params,
            reference_joints_deg=reference,
            camera_height_mm=camera_height_function(devices),
            record=self.record,
            session_id=sid,
            jobs=self.jobs,
            cell=station_cell(self.plan, _config_of(devices), self.measure_params),
            plan_of=get_plan,
            compute=self.compute,
            cancelled=lambda: self._abort,
        )

    def _steps(self, ctx: PlanContext) -> tuple[list[Step], list[Step]]:
        steps = list(self.plan.steps(self.params, ctx))
        planned = len(steps)
        prelude: list[Step] = []
        assert ctx.session_id is not None
        if self._resume is not None:
            rows = self.record.steps(ctx.session_id)
            self._run = 1 + max((int(r.data.get("run", 0)) for r in rows), default=0)
            done = {s.index for s in rows if s.state == "done"}
            remaining = [s for s in steps if s.index not in done]
            n_pre = sum(1 for s in rows if s.index >= PRELUDE_BASE)
            if remaining and done:
                remaining = self._redo(ctx, steps, remaining, done)
                for k, s in enumerate(self.plan.resume_prelude(self.params, ctx, remaining[0])):
                    prelude.append(Step(PRELUDE_BASE + n_pre + k, s.name, s.actions, s.meta))
            self._event(
                "resumed",
                {"skipped_steps": len(steps) - len(remaining), "remaining": len(remaining), "run": self._run},
            )
            steps = remaining
        with self._lock:
            # progress counts the plan's steps over the whole session: a resumed run continues the count
            # (a resume prelude re-establishes the set-up; its steps are not the plan's)
            self._total = planned
            self._done = planned - len(steps)
        return steps, prelude

    def _redo(self, ctx: PlanContext, steps: list[Step], remaining: list[Step], done: set[int]) -> list[Step]:
        """The plan's resume rule (``resume_from``): a resume reruns from that step on, done or not, so
        that no population mixes two runs. The rerun steps' earlier captures stay in the record, marked
        by an ``abandoned`` event, and the analysis takes the new attempt's."""
        rule = getattr(self.plan, "resume_from", None)
        if rule is None:
            return remaining
        assert ctx.session_id is not None
        first, reason = rule(self.params, ctx, steps, remaining[0])
        redo = {s.index for s in steps if s.index >= first}
        ids = [c.id for c in self.record.captures(ctx.session_id) if c.step_index in redo]
        if ids or redo & done:
            # every capture of the steps run again, the interrupted one's included: never analysed again
            self._event("abandoned", {"reason": reason, "steps": sorted(redo & done), "captures": ids})
        return [s for s in steps if s.index not in done or s.index >= first]

    def _check_progress(self, sid: str, ctx: PlanContext) -> None:
        """A plan's live gates (``check_progress``): once the step is stored and measured, the plan may
        stop the session at once (``GateError``) when what it measured cannot be right."""
        check = getattr(self.plan, "check_progress", None)
        if check is None and not self._scale.pending:
            return
        self._drain()
        self._check_store()
        captures = self._capture_results(sid)
        self._scale.first_capture(captures)  # the scale check, when pre-flight did not see the crossing
        if check is not None:
            check(self.params, ctx, captures)

    def _connect(self, stack: contextlib.ExitStack) -> None:
        devices = self.devices
        if devices is None:
            return
        for name in ("robot", "camera", "table", "distance_sensor"):
            device = getattr(devices, name)
            if device is None:
                continue
            device.connect()
            stack.callback(self._close, name, device)
        self._event("connected", {"devices": devices.identities()})

    def _close(self, name: str, device: Any) -> None:
        if name == "robot" and self._abort:
            # the runner may reach its clean-up while abort() is still writing the stop: never close
            # the port under it
            self._stop_sent.wait(5.0)
        try:
            device.close()
        except Exception as exc:  # noqa: BLE001 - the others must still be closed
            self._event("warning", {"message": f"closing the {name} failed: {exc}"})

    def _route(self, ctx: PlanContext, prelude: Sequence[Step]) -> tuple[list[Step], list[str]]:
        """The session's first motion: the arm's route to the plan's reference pose from where it is
        commanded (``station.arm_route``), as a step; none when the arm is there. For a plan that never
        moves the arm, the pre-flight problem when it is not there instead."""
        devices = self.devices
        robot = devices.robot if devices is not None else None
        pose = self.plan.reference_pose(self.params, ctx)
        if devices is None or robot is None or pose is None:
            return [], []
        try:
            start = tuple(robot.where().commanded_joints_deg)
        except DeviceError as exc:  # pre-flight says so too when the plan moves the arm
            why = f"the robot cannot be read (a {self.plan.name} needs the arm at its reference pose): {exc}"
            return [], [] if pose.route else [why]
        safety = devices.config.robot.safety if devices.config.robot is not None else None
        route = plan_route(start, pose.joints_deg, max_step_deg=max_step_of(safety))
        if not route.moves:
            return [], []
        if not pose.route:
            return [], [
                f"the arm is not at its reference pose ({describe_offset(start, route.target_deg)}); a"
                f" {self.plan.name} never moves the arm: {TO_REFERENCE_HINT}, then start again"
            ]
        assert ctx.session_id is not None
        used = [s.index for s in self.record.steps(ctx.session_id)] + [s.index for s in prelude]
        index = max([PRELUDE_BASE - 1, *used]) + 1
        how = "through the lift pose" if route.via_lift else "direct"
        meta = {"role": "route", "via_lift": route.via_lift, "start_deg": list(start)}
        step = Step(index, f"to the reference pose ({how})", tuple(MoveJoints(q) for q in route.moves), meta)
        # not one of the plan's steps: progress counts those (as it does not count a resume's prelude)
        return [step], []

    def _preflight(self, steps: Sequence[Step], problems: Sequence[str] = ()) -> None:
        """Every problem at once (``problems``: those found before), before anything moves."""
        problems = list(problems)
        devices = self.devices
        robot = devices.robot if devices is not None else None
        uses_robot = any(isinstance(a, MoveJoints | SetSpeed) for s in steps for a in s.actions)
        uses_table = any(isinstance(a, MoveTable) for s in steps for a in s.actions)
        start: tuple[float, ...] | None = None
        if robot is not None and uses_robot:
            try:
                robot.clear_stop()  # releases nothing: a latched stop is a problem, acknowledged locally
            except StopLatchedError as exc:
                problems.append(str(exc))
            try:
                status = robot.status()
                if status.power is False:
                    problems.append(
                        "the arm's power is off: switch it on at the controller, then start again"
                    )
                if status.homed is False:
                    problems.append(
                        "the arm is not homed: home it (station robot ... home), then start again"
                    )
                start = tuple(robot.where().commanded_joints_deg)
            except DeviceError as exc:
                problems.append(f"the robot cannot be read: {exc}")
        if robot is not None and uses_robot and start is not None:
            previous: Sequence[float] = start
            seen: set[tuple[tuple[float, ...], tuple[float, ...]]] = set()
            for step in steps:
                base: Sequence[float] = previous  # where a MoveOffset's offsets start (planned)
                for action in step.actions:
                    if isinstance(action, MoveOffset):
                        target = tuple(b + o for b, o in zip(base, action.offset_deg, strict=True))
                        try:
                            robot.check_move(target, start_deg=previous)
                        except MotionRejectedError as exc:
                            problems.append(f"{step.name}: {exc}")
                        previous = target
                        continue
                    if not isinstance(action, MoveJoints):
                        continue
                    base = action.target_deg
                    key = (tuple(previous), action.target_deg)
                    if key not in seen:
                        seen.add(key)
                        try:
                            robot.check_move(action.target_deg, start_deg=previous)
                        except MotionRejectedError as exc:
                            problems.append(f"{step.name}: {exc}")
                    previous = action.target_deg
            speeds: set[float] = set()
            for step in steps:  # every speed the plan sets, against the station's cap (the driver's check)
                for action in step.actions:
                    if isinstance(action, SetSpeed) and action.percent not in speeds:
                        speeds.add(action.percent)
                        try:
                            robot.check_speed(action.percent)
                        except MotionRejectedError as exc:
                            problems.append(f"{step.name}: {exc}")
        table = devices.table if devices is not None else None
        if table is not None and uses_table:
            checked: set[tuple[float, float]] = set()
            for step in steps:
                for action in step.actions:
                    if isinstance(action, MoveTable) and (action.x_mm, action.y_mm) not in checked:
                        checked.add((action.x_mm, action.y_mm))
                        try:
                            table.check_target(action.x_mm, action.y_mm)
                        except MotionRejectedError as exc:
                            problems.append(f"{step.name}: {exc}")
        if devices is not None:
            problems += self._scale.before_motion()  # the camera model and distance against the groove
        if len(problems) > 20:
            problems = [*problems[:20], f"... and {len(problems) - 20} more"]
        with self._lock:
            planned = self._total
        # ``steps``: every step checked (the route and a resume's prelude included); ``plan_steps``: the
        # plan's over the whole session, which progress counts
        self._event("preflight", {"problems": problems, "steps": len(steps), "plan_steps": planned})
        if problems:
            raise PreflightError(problems)

    def _safe_point(self) -> None:
        if self._pause or self._stop or self._abort:
            # what the last step captured is stored before the session rests (outside the lock: the
            # store thread reports its events under it)
            self._drain()
        with self._lock:
            if self._abort:
                raise _AbortRequestedError()
            if self._stop:
                raise _StopRequestedError()
            if self._pause:
                self._set_state(RunnerState.PAUSED)
                while self._pause and not (self._stop or self._abort):
                    self._cond.wait(0.5)
                if self._abort:
                    raise _AbortRequestedError()
                if self._stop:
                    raise _StopRequestedError()
                self._set_state(RunnerState.RUNNING)

    def _run_step(self, sid: str, step: Step, ctx: PlanContext) -> None:
        """Run the step's actions here; its captures are stored, measured and the step finished by the
        store thread, in order, while the next step's motions run (the arm never waits for the disk).
        A step is ``done`` in the record only once everything it captured is stored and measured."""
        self._check_store()
        t0 = time.monotonic()
        self.record.begin_step(sid, step.index, step.name, {**step.meta, **self._run_meta()})
        self._event("step_started", {"index": step.index, "name": step.name})
        data: dict[str, Any] = {}
        grabbed: list[tuple[list[Frame], dict[str, Any], int]] = []
        self._offset_base = None
        # frame indices of a step's n-th attempt start at n x FRAMES_PER_ATTEMPT (a resumed step never
        # overwrites or deletes what an interrupted attempt captured); a step's captures count up from there
        earlier = self.record.captures(sid, step_index=step.index)
        self._frame_base = (
            (max(c.frame_index for c in earlier) // FRAMES_PER_ATTEMPT + 1) * FRAMES_PER_ATTEMPT
            if earlier
            else 0
        )
        self._frames_in_step = 0
        try:
            for action in step.actions:
                if self._abort:
                    raise _AbortRequestedError()
                self._check_store()
                if isinstance(action, Capture):
                    grabbed.append(self._grab(action))
                elif isinstance(action, Align):
                    try:
                        data.update(self._align(sid, step, action, grabbed))
                    except AlignSkippedError as skipped:
                        data["skipped"] = str(skipped)
                        self._event("warning", {"message": f"{step.name}: {skipped}"})
                        break
                else:
                    data.update(self._act(step, action, ctx))
        except BaseException as exc:
            # what was grabbed before the failure is still stored (nothing captured is lost)
            reason = str(exc) or type(exc).__name__
            self._submit(lambda: self._store_step(sid, step, grabbed, data, t0, failed=reason))
            self._drain()
            if isinstance(exc, DeviceError) and step_moves(step):
                self._reread_position("motion error")
            raise
        self._submit(lambda: self._store_step(sid, step, grabbed, data, t0))

    def _store_step(
        self,
        sid: str,
        step: Step,
        grabbed: list[tuple[list[Frame], dict[str, Any], int]],
        data: dict[str, Any],
        t0: float,
        failed: str | None = None,
    ) -> None:
        """In the store thread: store and measure the step's frames, then finish the step."""
        try:
            ids = [
                cid for frames, meta, first in grabbed for cid in self._store(sid, step, frames, meta, first)
            ]
        except BaseException as exc:
            self.record.finish_step(sid, step.index, data={**data, "error": str(exc)}, state="failed")
            raise
        if ids:
            data = {**data, "captures": ids}
        if failed is not None:
            self.record.finish_step(sid, step.index, data={**data, "error": failed}, state="failed")
            return
        self.record.finish_step(sid, step.index, data=data)
        with self._lock:
            if step.index < PRELUDE_BASE:
                self._done += 1
            self._t_steps.append(time.monotonic() - t0)
        self._event(
            "step_finished", {"index": step.index, "name": step.name, "progress": self.progress().to_json()}
        )
        if self._captures >= EARLY_FAILURE_CAPTURES and self._measured_ok == 0:
            raise SessionError(
                f"none of the first {self._captures} captures could be measured (last: {self._last_error}); "
                "check that the crossing is in view and in focus, the lighting, and the measurement "
                "parameters, then start again"
            )

    # ------------------------------------------------------------------ the store thread

    def _submit(self, task: Callable[[], None]) -> None:
        if self._store_pool is None:
            task()
            return
        self._store_futures = [f for f in self._store_futures if not f.done() or f.exception() is not None]
        self._store_futures.append(self._store_pool.submit(task))
        # at most one step stored behind the arm: memory stays flat and errors surface within a step
        while sum(not f.done() for f in self._store_futures) > 1:
            next(f for f in self._store_futures if not f.done()).exception()  # waits for it

    def _check_store(self) -> None:
        """Raise the first error of the store thread (disk full, record lost ...) in the runner thread."""
        for f in self._store_futures:
            if f.done() and f.exception() is not None:
                exc = f.exception()
                self._store_futures = [g for g in self._store_futures if g is not f]
                assert exc is not None
                raise exc

    def _drain(self) -> None:
        """Wait until everything grabbed is stored; errors are left for ``_check_store``."""
        for f in list(self._store_futures):
            f.exception()

    def _act(self, step: Step, action: Action, ctx: PlanContext) -> dict[str, Any]:
        """Run one action through its handler (``_HANDLERS``, keyed by the action's type); the step's
        data it adds."""
        handler = _HANDLERS.get(type(action))
        if handler is None:
            raise PlanError(f"unknown action {action!r}")
        return handler(self, step, action, ctx)

    def _devices(self) -> StationDevices:
        assert self.devices is not None  # a plan with device actions runs with devices (pre-flight)
        return self.devices

    def _set_speed(self, action: SetSpeed) -> dict[str, Any]:
        require(self._devices().robot, "robot").set_speed(action.percent)
        return {}

    def _move_joints(self, action: MoveJoints) -> dict[str, Any]:
        require(self._devices().robot, "robot").move_joints(action.target_deg)
        self._offset_base = tuple(action.target_deg)
        return {}

    def _move_offset(self, action: MoveOffset) -> dict[str, Any]:
        robot = require(self._devices().robot, "robot")
        if self._offset_base is None:
            raise PlanError("a MoveOffset needs a MoveJoints or an Align before it in its step")
        target = tuple(b + o for b, o in zip(self._offset_base, action.offset_deg, strict=True))
        robot.check_move(target)  # from where the arm is: the aligned pose differs from the planned one
        robot.move_joints(target)
        return {}

    def _move_table(self, step: Step, action: MoveTable) -> dict[str, Any]:
        devices = self._devices()
        table = require(devices.table, "table")
        timeout = getattr(self.params, "prompt_timeout_s", None)
        # the operator's prompt says which position of how many, whether this is the overshoot, and
        # whether it is a resume's check of the last confirmed position
        at = step.meta.get("position")  # a resume's check repeats an earlier position
        details: dict[str, str | float] = {
            "position": (at if isinstance(at, int) else step.index) + 1,
            "positions": self._total,
            "move": "overshoot" if action.overshoot else "position",
        }
        if step.meta.get("role") == "resume_check":
            details["purpose"] = "resume_check"
        with devices.broker.context(**details):
            pos = table.move_to(action.x_mm, action.y_mm, timeout_s=timeout)
        return {} if action.overshoot else {"table_confirmed_mm": [pos.x_mm, pos.y_mm]}

    def _settle(self, action: Settle) -> dict[str, Any]:
        with self._lock:
            self._cond.wait_for(lambda: self._abort, timeout=action.seconds)
        if self._abort:
            raise _AbortRequestedError()
        return {}

    def _align(
        self,
        sid: str,
        step: Step,
        action: Align,
        grabbed: list[tuple[list[Frame], dict[str, Any], int]],
    ) -> dict[str, Any]:
        """Measure, correct within bounds, check, move; repeat (see :class:`~station.plans.Align`)."""
        devices = self.devices
        assert devices is not None
        robot = require(devices.robot, "robot")
        planned = action.planned_deg
        corrections: list[dict[str, Any]] = []
        for iteration in range(action.max_iterations + 1):
            capture = self._grab(Capture(1, {**action.meta, "iteration": iteration}))
            grabbed.append(capture)  # stored like any capture: nothing captured is lost
            frames, meta, _ = capture
            z_mm = meta.get("z_mm")  # the distance sensor's reading with the frame (None without one)
            image = frames[0].image
            center: tuple[float, float] | None = None
            error: str | None = None
            try:
                m = measure(image, self.measure_params)
                center = (float(m.center_px[0]), float(m.center_px[1]))
            except MeasurementError as exc:
                error = exc.message
            joints = tuple(float(a) for a in meta.get("joints_deg", planned))
            seen = AlignInput(joints, center, z_mm, (int(image.shape[1]), int(image.shape[0])), error)
            correction = action.correct(seen)
            if correction is None:
                # offsets start from where the controller was commanded (its own 0.001 deg grid)
                commanded = meta.get("commanded_joints_deg", joints)
                self._offset_base = tuple(float(a) for a in commanded)
                return {"aligned_joints_deg": list(joints), "corrections": corrections}
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
                with self._lock:
                    self._cond.wait_for(lambda: self._abort, timeout=action.settle_s)
                if self._abort:
                    raise _AbortRequestedError()
        raise AlignSkippedError(
            f"not aligned after {action.max_iterations} corrections: configuration skipped"
        )

    def _grab(self, action: Capture) -> tuple[list[Frame], dict[str, Any], int]:
        """In the runner thread (the devices' only user): where the arm is, then the frames."""
        devices = self.devices
        assert devices is not None
        meta: dict[str, Any] = {**action.meta, **self._run_meta()}
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
        first = self._frame_base + self._frames_in_step
        frames = devices.camera.grab_many(action.frames)
        self._frames_in_step += len(frames)
        return frames, meta, first

    def _run_meta(self) -> dict[str, int]:
        """``{"run": n}`` for the n-th resumed run of a session (nothing for its first: unchanged)."""
        return {"run": self._run} if self._run else {}

    def _read_z(self, sensor: DistanceSensor) -> tuple[float | None, str | None]:
        """The distance sensor's reading for a capture: (mm, None), or (None, why) when it has no valid
        distance (out of range, alarm: the capture goes on, its z is missing). A garbled or lost reply
        is read once more; a second failure, or a lost link, fails the step."""
        for attempt in (1, 2):
            try:
                return sensor.read_mm(), None
            except (OutOfRangeError, SensorAlarmError) as exc:
                self._event("warning", {"message": f"no z with this capture: {exc}"})
                return None, str(exc)
            except (DeviceProtocolError, DeviceTimeoutError) as exc:
                if attempt == 2:
                    raise
                self._event("warning", {"message": f"distance sensor: {exc}; reading again"})
        raise AssertionError("unreachable")

    def _store(
        self, sid: str, step: Step, frames: list[Frame], meta: dict[str, Any], first: int
    ) -> list[int]:
        """Store each frame (lossless, fsynced), then measure it from the stored file and record that."""
        ids = []
        params_doc = self.measure_params.model_dump(mode="json")
        software = f"station {__version__}"
        for fi, frame in enumerate(frames):
            cap = self.record.save_capture(
                sid,
                step.index,
                first + fi,
                frame.image,
                timestamp_s=frame.timestamp_s,
                meta={**meta, "frame_id": frame.frame_id},
                z_mm=meta.get("z_mm"),
            )
            self._captures += 1
            self._event(
                "image_captured", {"capture_id": cap.id, "path": cap.path, "step": step.index, "frame": fi}
            )
            result = measure_file(Path(self.record.data_dir) / cap.path, self.measure_params).to_json()
            result["file"] = cap.path
            if self.scale_calibration is not None and result.get("ok"):
                result.setdefault("diagnostics", {})["scale_calibration"] = self.scale_calibration
            self.record.add_measurement(sid, cap.id, result, params=params_doc, software=software)
            ok = bool(result.get("ok"))
            self._measured_ok += ok
            if not ok:
                self._last_error = result.get("error")
            self._event(
                "measurement",
                {
                    "capture_id": cap.id,
                    "ok": ok,
                    "center_px": result.get("center_px"),
                    "center_mm": result.get("center_mm"),
                    "z_mm": meta.get("z_mm"),
                    "error": result.get("error"),
                    "code": result.get("code"),
                },
            )
            ids.append(cap.id)
        return ids

    def _return_to_reference(self) -> None:
        devices = self.devices
        reference = devices.reference_joints_deg if devices is not None else None
        if devices is None or devices.robot is None or reference is None or "robot" not in self.plan.needs:
            return
        safety = devices.config.robot.safety if devices.config.robot is not None else None
        try:
            done = go_to_reference(devices.robot, reference, max_step_deg=max_step_of(safety))
            self._event("returned", {"joints_deg": list(reference), "moves": done.moves})
        except DeviceError as exc:
            self._event("warning", {"message": f"could not return to the reference pose: {exc}"})

    # ------------------------------------------------------------------ states and events

    def _set_state(self, state: RunnerState) -> None:
        with self._lock:
            if state is self._state:
                return
            was = self._state
            self._state = state
        if self._session_id is not None:
            if state not in FINAL_STATES:
                self.record.set_state(self._session_id, state)
            self._event("state", {"state": str(state), "was": str(was)})

    def _set_state_if_active(self, state: RunnerState | None) -> None:
        if state is not None and self._state not in FINAL_STATES:
            self._set_state(state)

    def _event(self, kind: str, data: dict[str, Any]) -> None:
        if self._session_id is None:
            return
        with self._lock:  # the runner and the store thread both report: one order, one lock (no ABBA)
            try:
                event = self.record.add_event(self._session_id, kind, data)
            except RecordError as exc:
                log.error("event %s not recorded: %s", kind, exc)
                return
            for listener in list(self._listeners):
                try:
                    listener(event)
                except Exception:
                    log.exception("event listener failed")

    def _on_prompt(self, event: PromptEvent) -> None:
        p = event.prompt
        if event.kind == "opened":
            # the state first: a client that sees the prompt finds the session waiting on it
            with self._lock:
                if self._state in (RunnerState.RUNNING, RunnerState.PAUSING):
                    self._set_state(RunnerState.AWAITING_OPERATOR)
            self._event(
                "prompt_raised",
                {"id": p.id, "kind": p.kind, "message": p.message, "fields": [f.__dict__ for f in p.fields]},
            )
        else:
            a = event.answer
            self._event(
                "prompt_answered",
                {
                    "id": p.id,
                    "outcome": str(a.outcome) if a else None,
                    "readings": dict(a.readings) if a else {},
                    "by": a.by if a else "",
                    "reason": a.reason if a else "",
                },
            )
            with self._lock:
                if self._state is RunnerState.AWAITING_OPERATOR:
                    self._set_state(RunnerState.PAUSING if self._pause else RunnerState.RUNNING)


Handler = Callable[[SessionRunner, Step, Any, PlanContext], dict[str, Any]]

_HANDLERS: dict[type, Handler] = {
    Compute: lambda runner, step, action, ctx: action.run(ctx),
    DeviceCheck: lambda runner, step, action, ctx: action.run(runner._devices()),
    SetSpeed: lambda runner, step, action, ctx: runner._set_speed(action),
    MoveJoints: lambda runner, step, action, ctx: runner._move_joints(action),
    MoveOffset: lambda runner, step, action, ctx: runner._move_offset(action),
    MoveTable: lambda runner, step, action, ctx: runner._move_table(step, action),
    Settle: lambda runner, step, action, ctx: runner._settle(action),
}
"""The action executor: each action type's handler (a capture and an align are the step's own: they
need the frames grabbed so far); a handler takes what it uses."""


def require(device: Any, name: str) -> Any:
    if device is None:
        raise SessionError(f"this step needs the {name}, which the station configuration does not have")
    return device


def stored_captures(record: Record, source: str, *, measured_in: str | None = None) -> list[CaptureResult]:
    """The captures of session ``source``'s completed steps with the measurements session ``measured_in``
    recorded of them (the source's own by default): what a plan's analysis gets."""
    measurements = {m.capture_id: m for m in record.measurements(measured_in or source)}
    done = {s.index for s in record.steps(source) if s.state == "done"}
    caps = [c for c in record.captures(source) if c.step_index in done]
    # a step run again after an interruption keeps its earlier attempt's frames (nothing captured is
    # lost); the analysis takes the attempt that completed: the latest
    latest: dict[int, int] = {}
    for c in caps:
        latest[c.step_index] = max(latest.get(c.step_index, 0), c.frame_index // FRAMES_PER_ATTEMPT)
    out = []
    for cap in caps:
        if cap.frame_index // FRAMES_PER_ATTEMPT != latest[cap.step_index]:
            continue
        m = measurements.get(cap.id)
        out.append(
            CaptureResult(
                cap.id,
                cap.step_index,
                cap.frame_index,
                cap.meta,
                m.result if m else None,
                cap.width,
                cap.height,
                cap.z_mm,
            )
        )
    return out


def _config_of(devices: StationDevices | None) -> dict[str, Any] | None:
    """The live station's configuration as JSON (what a plan's ``cell_from_config`` reads); ``None``
    without devices (an offline session)."""
    return devices.config.model_dump(mode="json") if devices is not None else None


def step_moves(step: Step) -> bool:
    return any(isinstance(a, MoveJoints | MoveTable | MoveOffset | Align) for a in step.actions)


def camera_height_function(devices: StationDevices | None) -> Callable[[Sequence[float]], float] | None:
    """Height of the camera's front above the artifact plane for given joints, from the robot's safety
    settings (``table_z_mm``, ``camera_offset_mm``) and the nominal kinematics; ``None`` when unknown."""
    if devices is None or devices.config.robot is None:
        return None
    from station.plans._recorded import camera_height_function as from_safety

    return from_safety(devices.config.robot.safety)
