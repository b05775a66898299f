"""Sessions in a process of their own: the station's devices and its session runner, away from a front
end's interpreter.

A front end that serves many clients (``station serve``) spends its interpreter's time on requests; a
session runner sharing that interpreter waits for it at every hand-over of the GIL (a serial reply, a
frame, a record write), and the arm's cycle stretches with the number of clients. So the service keeps
the HTTP side and the record's reads, and a *station worker* process owns everything that drives
hardware:

- :class:`SessionHost` (in the worker) builds the devices once (a configuration's, or the simulated
  station's), creates and runs one :class:`~station.runner.SessionRunner` at a time in a thread, and
  answers the operator prompts through the station's :class:`~station.prompts.PromptBroker`;
- :class:`StationWorker` (in the front end) starts the worker, calls it (``create``, ``act``,
  ``confirm`` ...) and mirrors what it reports: the runner's events with its state and progress, the
  operator prompt that is open, and the worker's log records (re-emitted through the front end's own
  loggers). Reads of the mirror never cross the process boundary.

Both processes open the same record (SQLite in WAL mode, or the configured server): the runner writes
it, the front end reads it. An event reaches the front end after the runner has committed it, so a
front end that sees a ``state`` event reads the new row.

The worker's exceptions come back as the same types (a ``PreflightError`` is a ``PreflightError``).
The worker never outlives its front end: it ignores Ctrl-C (the front end shuts it down in order), and
when its pipe closes or it gets SIGTERM it aborts the running session (the robot stopped through its
latched ``stop()``), records it as ``interrupted`` and closes the devices.
"""

from __future__ import annotations

import contextlib
import importlib
import itertools
import logging
import os
import signal
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, Pipe
from pathlib import Path
from typing import Any

from station.compute import ComputeSpec, open_backend
from station.kinds import get_plan
from station.plans import parse_params
from station.prompts import Prompt, PromptAnswer, PromptBroker, PromptEvent
from station.record import (
    EventRow,
    RecordError,
    RecordUnavailableError,
    SessionLockError,
    lock_holder,
    station_lock,
)
from station.runner import (
    FINAL_STATES,
    PreflightError,
    Progress,
    RunnerState,
    SessionError,
    SessionRunner,
)
from station.vision import MeasureParams

log = logging.getLogger(__name__)

WORKER_NICE = -10
"""The worker's default nice value (see :attr:`WorkerSpec.nice`)."""

START_TIMEOUT_S = 120.0
"""The longest the front end waits for the worker to build the station's devices."""
RECORD_RETRY_S = 1.0
"""How often the worker tries again to record a failure the record could not take (it was unreachable)."""


class ConflictError(SessionError):
    """The request does not fit the session's or the station's state (HTTP 409)."""


class NotAvailableError(SessionError):
    """The station has no such device or feature in this configuration (HTTP 409)."""


class WorkerError(NotAvailableError):
    """The station's worker process is not there (it failed to start, or died); restart the service."""


@dataclass(frozen=True)
class WorkerSpec:
    """What the worker builds: the record's place and the station (a configuration, or the sim)."""

    sim: bool = False
    manual_prompts: bool = False
    config: Path | None = None
    data: Path | None = None
    database: str | None = field(default=None, repr=False)  # a URL may hold a password
    sim_options: dict[str, Any] = field(default_factory=dict)
    log_level: int = logging.INFO
    """The worker's log records at this level and above reach the front end's loggers (which filter them
    again by their own levels)."""
    nice: int = WORKER_NICE
    """The worker's scheduling priority (a nice value; negative is preferred): when the machine is short
    of CPU, the clients wait, not the arm. Lowering it needs the right to (root, or CAP_SYS_NICE, e.g.
    systemd's ``LimitNICE=``); without it the worker keeps the front end's priority."""


@dataclass(frozen=True)
class StationInfo:
    """The station the worker built: which devices it has, their identities, its configuration."""

    devices: tuple[str, ...]
    identities: dict[str, Any]
    name: str | None
    config_snapshot: dict[str, Any] | None
    nice: int = 0
    """The worker's scheduling priority (nice value) as it runs."""


@dataclass(frozen=True)
class RunnerStatus:
    """The worker's latest session as of its latest event."""

    session_id: str
    kind: str
    state: RunnerState
    progress: Progress
    error: str | None = None
    """Set when the session failed in a way its runner could not record (the record unreachable, an
    error of the worker's own): the front end shows it ``failed`` with this reason meanwhile."""


DEVICE_NAMES = ("robot", "camera", "table", "distance_sensor")
NO_REFERENCE = (
    "this station has no robot with a reference pose (configure [robot] with reference_joints_deg, or start"
    " the service with --sim)"
)
"""Why the arm's reference-pose route is not available."""


# --------------------------------------------------------------------------- exceptions over the pipe


def _pack_exception(exc: BaseException) -> tuple[str, str, tuple[Any, ...], dict[str, Any], str]:
    return (type(exc).__module__, type(exc).__qualname__, exc.args, dict(vars(exc)), str(exc))


def _unpack_exception(packed: tuple[str, str, tuple[Any, ...], dict[str, Any], str]) -> BaseException:
    """The same exception type with the same attributes (its ``__init__`` is not called again: many of
    the project's exceptions take other arguments than their message)."""
    module, qualname, args, attrs, text = packed
    try:
        cls: Any = importlib.import_module(module)
        for part in qualname.split("."):
            cls = getattr(cls, part)
        if not (isinstance(cls, type) and issubclass(cls, BaseException)):
            raise TypeError(qualname)
        exc: BaseException = cls.__new__(cls)
        BaseException.__init__(exc, *args)
        vars(exc).update(attrs)
        return exc
    except Exception:  # noqa: BLE001 - an exception type the front end cannot import
        return SessionError(f"{qualname}: {text}")


class _Pipe:
    """One end of the pipe; ``send`` from any thread (a Connection is not safe for concurrent sends)."""

    def __init__(self, conn: Connection) -> None:
        self.conn = conn
        self._lock = threading.Lock()

    def send(self, message: tuple[Any, ...]) -> None:
        with self._lock:
            self.conn.send(message)


# --------------------------------------------------------------------------- the worker's side


class SessionHost:
    """The worker's station: its record, devices, and at most one running session.

    The methods named ``rpc_*`` are what the front end calls; each runs in a thread of its own so that
    an ``abort`` is never queued behind a ``create`` that waits for pre-flight.
    """

    def __init__(self, spec: WorkerSpec, send: Callable[[tuple[Any, ...]], None]) -> None:
        from station.config import load_config, open_sim_station, open_station
        from station.session import open_record

        self.spec = spec
        self._send = send
        self.config = load_config(spec.config) if spec.config else None
        self.record = open_record(spec.data, spec.database, self.config)
        self.devices: Any = None
        try:
            if spec.sim:
                self.devices = open_sim_station(operator=not spec.manual_prompts, **spec.sim_options)
            elif self.config is not None:
                self.devices = open_station(self.config)
        except BaseException:
            self.record.close()
            raise
        self._lock = threading.RLock()
        self._runner: SessionRunner | None = None
        self._thread: threading.Thread | None = None
        self._closed = False
        self._moving = False  # the arm is on its way to the reference pose (rpc_to_reference)
        self._closing = threading.Event()
        self._listeners: list[Callable[[EventRow], None]] = []
        self._prompt_watch: threading.Thread | None = None
        self._prompt_events: list[PromptEvent] = []
        self._prompt_cond = threading.Condition()
        # where re-analyses and sweeps measure: the configuration's [compute] (a cluster is reached
        # on the first session that needs it, and again after it was lost)
        cfg = self.station_config
        self.compute = open_backend(cfg.compute.spec() if cfg is not None else ComputeSpec())
        if self.devices is not None:
            self.devices.broker.subscribe(self._on_prompt_event)
            self._prompt_watch = threading.Thread(target=self._forward_prompts, name="prompts", daemon=True)
            self._prompt_watch.start()

    # ------------------------------------------------------------------ what the front end mirrors

    @property
    def station_config(self) -> Any:
        """The station's configuration: the devices' (the sim's), else the one given; None offline."""
        return self.devices.config if self.devices is not None else self.config

    def info(self) -> StationInfo:
        devices = self.devices
        config = self.station_config
        present = tuple(n for n in DEVICE_NAMES if devices is not None and getattr(devices, n) is not None)
        return StationInfo(
            devices=present,
            identities=devices.identities() if devices is not None else {},
            name=config.name if config is not None else None,
            config_snapshot=config.snapshot() if config is not None else None,
            nice=os.getpriority(os.PRIO_PROCESS, 0),
        )

    def subscribe(self, listener: Callable[[EventRow], None]) -> None:
        """Also call ``listener(event)`` in the worker for every event (benchmarks' meters)."""
        self._listeners.append(listener)

    def _on_event(self, runner: SessionRunner, event: EventRow) -> None:
        # the runner's thread (or its store thread), under the runner's lock: quick work only
        for listener in list(self._listeners):
            try:
                listener(event)
            except Exception:
                log.exception("event listener failed")
        assert runner.session_id is not None
        status = RunnerStatus(runner.session_id, runner.plan.name, runner.state, runner.progress())
        self._send(("event", event, status))

    def _on_prompt_event(self, event: PromptEvent) -> None:
        with self._prompt_cond:
            self._prompt_events.append(event)
            self._prompt_cond.notify_all()

    def _forward_prompts(self) -> None:
        """Report each prompt once it is *shown* (every listener of the broker has seen it open, e.g. the
        runner, which sets the session's state first), and its closing."""
        broker: PromptBroker = self.devices.broker
        while True:
            with self._prompt_cond:
                self._prompt_cond.wait_for(lambda: bool(self._prompt_events) or self._closed)
                if self._closed:
                    return
                event = self._prompt_events.pop(0)
            if event.kind != "opened":
                self._send(("prompt", None, event.prompt.id))
                continue
            while not self._closed:
                shown = broker.wait_for_prompt(0.05)
                if shown is not None and shown.id == event.prompt.id:
                    self._send(("prompt", shown, shown.id))
                    break
                pending = broker.current(pending=True)
                if pending is None or pending.id != event.prompt.id:
                    break  # closed before it was shown: its closing follows

    # ------------------------------------------------------------------ sessions

    def rpc_create(self, kind: str, params: Mapping[str, Any], assignments: Mapping[str, Any]) -> str:
        """Create and start a session; its id once pre-flight has passed (PreflightError otherwise)."""
        from station.session import session_measure_params

        plan = get_plan(kind)  # PlanError naming the plans (the service checked the kind first)
        plan_params = parse_params(plan, dict(params))
        if plan.needs and self.devices is None:
            raise NotAvailableError(
                f"a {kind} session drives hardware, and this service has no station: start it with --sim "
                "or --config FILE"
            )
        measure_params, cal_doc = session_measure_params(
            self.record, kind, dict(params), self.config, assignments
        )
        return self._start(
            SessionRunner(
                self.record,
                plan,
                plan_params,
                devices=self.devices if plan.needs else None,
                measure_params=measure_params,
                scale_calibration=cal_doc,
                station=self._station_name(),
                compute=self.compute,
            )
        )

    def rpc_resume(self, session_id: str) -> str:
        """Continue an interrupted, stopped, failed or aborted session of the record."""
        row = self.record.get_session(session_id)
        plan = get_plan(row.kind)
        if plan.needs and self.devices is None:
            raise NotAvailableError(
                f"session {row.id} drives hardware; start the service with --sim or --config"
            )
        return self._start(
            SessionRunner(
                self.record,
                plan,
                parse_params(plan, dict(row.params.get("plan", {}))),
                devices=self.devices if plan.needs else None,
                measure_params=MeasureParams.model_validate(row.params.get("measure", {})),
                scale_calibration=row.params.get("scale_calibration"),
                resume_session=row,
                station=self._station_name(),
                compute=self.compute,
            )
        )

    def rpc_act(self, session_id: str, action: str) -> bool:
        """pause, resume, stop or abort this worker's running session; False when it runs no such
        session (the front end then decides from the record)."""
        runner = self._active()
        if runner is None or runner.session_id != session_id:
            return False
        try:
            getattr(runner, action)()
        except SessionError as exc:
            raise ConflictError(str(exc)) from exc
        return True

    def rpc_wait(self, timeout_s: float | None = None) -> bool:
        """Wait for the session's thread to end; True when it has."""
        thread = self._thread
        if thread is None:
            return True
        thread.join(timeout_s)
        return not thread.is_alive()

    def _active(self) -> SessionRunner | None:
        """The running session's runner: not ended, and its thread still there (a runner that failed
        before it could set its own final state has ended all the same)."""
        runner, thread = self._runner, self._thread
        if runner is None or runner.state in FINAL_STATES or thread is None or not thread.is_alive():
            return None
        return runner

    def _station_name(self) -> str:
        config = self.station_config
        return str(config.name) if config is not None else "default"

    def _start(self, runner: SessionRunner) -> str:
        with self._lock:
            if self._closed:
                raise ConflictError("the service is shutting down")
            current = self._active()
            if current is not None:
                raise ConflictError(
                    f"session {current.session_id} ({current.plan.name}) is {current.state}: one session "
                    "at a time; wait for it to end, or stop or abort it first"
                )
            if self._moving:
                raise ConflictError(
                    "the arm is on its way to its reference pose (to-reference): start once it has arrived"
                )
            holder = lock_holder(self.record.data_dir)
            if holder is not None:
                raise SessionLockError(str(self.record.data_dir / "station.lock"), holder)
            runner.subscribe(lambda e: self._on_event(runner, e))
            checked = threading.Event()
            problems: list[str] = []

            def on_event(e: EventRow) -> None:
                if e.type == "preflight":
                    problems.extend(str(p) for p in e.data.get("problems", []))
                    checked.set()
                elif e.type == "state" and e.data.get("state") in FINAL_STATES:
                    checked.set()

            unsubscribe = runner.subscribe(on_event)
            runner.create()
            self._runner = runner
            thread = threading.Thread(target=self._run, args=(runner,), name="session", daemon=True)
            self._thread = thread
            thread.start()
        # the answer waits for pre-flight (devices connected, every motion checked; nothing moved yet), so
        # that out-of-limit targets are refused with the request, and shows the session under way
        while not checked.wait(0.05) and thread.is_alive():
            pass
        unsubscribe()
        if problems:
            thread.join()
            raise PreflightError(problems)
        assert runner.session_id is not None
        return runner.session_id

    def _run(self, runner: SessionRunner) -> None:
        try:
            runner.run()
        except Exception as exc:
            if isinstance(exc, SessionLockError):
                log.error("session %s could not start: %s", runner.session_id, exc)
            elif isinstance(exc, RecordError):  # the record's own words say it all
                log.error("session %s ended: %s", runner.session_id, exc)
            else:
                log.exception("session %s ended with an error", runner.session_id)
            self._failed(runner, exc)
            return

    def _failed(self, runner: SessionRunner, exc: BaseException) -> None:
        """The session ended with an exception its runner did not record (the record gone, an error of
        the worker's own): the front end learns it now, the record as soon as it can be reached."""
        sid = runner.session_id
        if sid is None:
            return
        done = runner.progress()
        status = RunnerStatus(
            sid,
            runner.plan.name,
            RunnerState.FAILED,
            Progress.model_construct(done=done.done, total=done.total, eta_s=None),
            error=str(exc) or type(exc).__name__,
        )
        with contextlib.suppress(OSError, ValueError):
            self._send(("ended", status))
        threading.Thread(
            target=self._record_failure, args=(status,), name="record-failure", daemon=True
        ).start()

    def _record_failure(self, status: RunnerStatus) -> None:
        """Record ``status``'s failure (unless the session's row already has a final state), trying again
        every ``RECORD_RETRY_S`` while the record cannot be reached and the worker runs."""
        sid = status.session_id
        while not self._closing.is_set():
            try:
                row = self.record.get_session(sid)
                if row.state in FINAL_STATES:
                    return
                self.record.set_state(sid, RunnerState.FAILED, error=status.error)
                event = self.record.add_event(
                    sid, "state", {"state": str(RunnerState.FAILED), "was": row.state}
                )
            except RecordUnavailableError:
                self._closing.wait(RECORD_RETRY_S)
                continue
            except RecordError as exc:
                log.error("session %s: its failure could not be recorded: %s", sid, exc)
                return
            log.info("session %s recorded as failed (%s)", sid, status.error)
            with contextlib.suppress(OSError, ValueError):
                self._send(("event", event, status))
            return

    # ------------------------------------------------------------------ prompts and the camera

    def _broker(self) -> PromptBroker:
        if self.devices is None:
            raise NotAvailableError("this service has no station, so no operator prompts")
        broker: PromptBroker = self.devices.broker
        return broker

    def rpc_confirm(self, prompt_id: str, readings: Mapping[str, float] | None, by: str) -> PromptAnswer:
        return self._broker().confirm(prompt_id, readings, by=by)

    def rpc_cancel(self, prompt_id: str, reason: str, by: str) -> PromptAnswer:
        return self._broker().cancel(prompt_id, reason=reason, by=by)

    def _settle(self) -> None:
        """Wait for an ended session's thread to finish: it publishes its final state before it lets go
        of the station lock, and a read of a device right then would find the station busy."""
        thread, runner = self._thread, self._runner
        if thread is not None and runner is not None and runner.state in FINAL_STATES:
            thread.join(30)

    def rpc_grab(self) -> Any:
        """One frame from the camera (ConflictError while a session owns it)."""
        self._settle()
        with self._lock:
            if self._active() is not None:
                raise ConflictError(
                    "a session owns the camera: its latest capture is at /api/v1/sessions/{id}/latest.png"
                )
            if self.devices is None:
                raise NotAvailableError("this service has no station (start it with --sim or --config)")
            holder = None if self._moving else lock_holder(self.record.data_dir)  # ours while it moves
            if holder is not None:
                raise SessionLockError(str(self.record.data_dir / "station.lock"), holder)
            camera = self.devices.camera
            camera.connect()
            try:
                return camera.grab().image
            finally:
                camera.close()

    # ------------------------------------------------------------------ the arm outside sessions

    def _idle_robot(self, what: str) -> Any:
        """The robot (None without one) when no session runs, the arm is not already moving and no other
        process holds the station (ConflictError, SessionLockError otherwise); call with the lock held."""
        runner = self._runner
        if self._closed:
            raise ConflictError("the service is shutting down")
        if runner is not None and runner.state not in FINAL_STATES:
            raise ConflictError(
                f"session {runner.session_id} ({runner.plan.name}) is {runner.state} and owns the arm: {what}"
                " once it has ended (or stop or abort it first)"
            )
        if self._moving:
            raise ConflictError(f"the arm is on its way to its reference pose: {what} once it has arrived")
        robot = self.devices.robot if self.devices is not None else None
        if robot is None:
            return None
        holder = lock_holder(self.record.data_dir)
        if holder is not None:
            raise SessionLockError(str(self.record.data_dir / "station.lock"), holder)
        return robot

    def rpc_robot_state(self) -> dict[str, Any] | None:
        """The arm read now, in one connection (connect, read, close: nothing moves): ``identity``,
        ``power``, ``homed``, ``joints_deg``, ``commanded_joints_deg``, ``world_mm_deg`` and, when the
        station has a reference pose, ``reference_joints_deg``, ``at_reference`` and the ``route``
        ``to-reference`` would take from here with every problem the driver's checks find in it
        (``station.arm_route.robot_status``; else those three are None). None without a robot.
        ConflictError while a session owns the arm or it is on its way; SessionLockError while another
        process holds the station."""
        from dataclasses import asdict

        from station.arm_route import ArmPose, robot_status

        self._settle()
        with self._lock:
            robot = self._idle_robot("read it")
            if robot is None:
                return None
            reference = self.devices.reference_joints_deg
            robot.connect()
            try:
                status, identity = robot.status(), robot.identity()
                if reference is not None:
                    arm = robot_status(robot, reference, self._max_step())
                    position = arm.position
                    against: dict[str, Any] = {
                        "reference_joints_deg": arm.reference_joints_deg,
                        "at_reference": arm.at_reference,
                        "route": arm.route.model_dump(mode="json"),
                    }
                else:
                    position = ArmPose.of(robot.where())
                    against = {"reference_joints_deg": None, "at_reference": None, "route": None}
            finally:
                robot.close()
        return {
            "identity": asdict(identity),
            "power": status.power,
            "homed": status.homed,
            **position.model_dump(mode="json"),
            **against,
        }

    def rpc_to_reference(self) -> dict[str, Any]:
        """Take the arm to the station's reference pose along its route (``station.arm_route``), every move
        checked before the first is sent (RouteRejectedError: nothing moved); what it did, as JSON."""
        from station.arm_route import go_to_reference

        with self._lock:
            robot = self._idle_robot("move it")
            if robot is None or self.devices.reference_joints_deg is None:
                raise NotAvailableError(NO_REFERENCE)
            self._moving = True
        try:
            with station_lock(self.record.data_dir, "to-reference"):
                robot.connect()
                try:
                    robot.clear_stop()  # an operator's command, as a session's start is
                    result = go_to_reference(
                        robot, self.devices.reference_joints_deg, max_step_deg=self._max_step()
                    )
                finally:
                    robot.close()
        finally:
            with self._lock:
                self._moving = False
        log.info("the arm is at its reference pose after %d move(s)", len(result.moves))
        return result.model_dump(mode="json")

    def _max_step(self) -> float:
        from station.arm_route import max_step_of

        robot = self.devices.config.robot
        return max_step_of(robot.safety if robot is not None else None)

    def rpc_call(self, fn: Callable[..., Any], args: tuple[Any, ...]) -> Any:
        """``fn(host, *args)`` in the worker: tests and benchmarks reach a simulated station's truth."""
        return fn(self, *args)

    # ------------------------------------------------------------------ shutdown

    def rpc_shutdown(self, timeout_s: float = 30.0) -> None:
        self.shutdown(timeout_s)

    def shutdown(self, timeout_s: float = 30.0, *, why: str = "the service shut down") -> None:
        """Idempotent: a running session is aborted (the robot stopped through its latched ``stop()``,
        the open prompt cancelled), then recorded as ``interrupted`` so that it can be resumed; the
        devices and the record are closed."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._closing.set()
        with self._prompt_cond:
            self._prompt_cond.notify_all()
        if self._moving and self.devices is not None and self.devices.robot is not None:
            with contextlib.suppress(Exception):
                self.devices.robot.stop()  # the arm on its way to the reference pose stops too
        runner, thread = self._runner, self._thread
        if runner is not None and thread is not None and thread.is_alive():
            sid = runner.session_id
            log.warning("%s: session %s is interrupted (the robot is stopped)", why, sid)
            runner.abort(why)
            thread.join(timeout_s)
            if sid is not None and not thread.is_alive():
                with contextlib.suppress(RecordError):
                    self.record.set_state(sid, RunnerState.INTERRUPTED, error=f"{why} during the session")
                    event = self.record.add_event(
                        sid, "state", {"state": str(RunnerState.INTERRUPTED), "was": str(runner.state)}
                    )
                    progress = runner.progress()
                    status = RunnerStatus(sid, runner.plan.name, RunnerState.INTERRUPTED, progress)
                    with contextlib.suppress(OSError, ValueError):
                        self._send(("event", event, status))
        if self.devices is not None:
            self.devices.close_owned()
        self.compute.close()
        self.record.close()


class _PipeLogHandler(logging.Handler):
    """The worker's log records, formatted here, re-emitted by the front end's loggers."""

    def __init__(self, send: Callable[[tuple[Any, ...]], None]) -> None:
        super().__init__()
        self._send = send
        self._formatter = logging.Formatter()

    def emit(self, record: logging.LogRecord) -> None:
        try:
            doc = {
                "name": record.name,
                "levelno": record.levelno,
                "levelname": record.levelname,
                "msg": record.getMessage(),
                "pathname": record.pathname,
                "lineno": record.lineno,
                "funcName": record.funcName,
                "created": record.created,
                "msecs": record.msecs,
                "threadName": f"worker:{record.threadName}",
                "processName": "station-worker",
                "exc_text": self._formatter.formatException(record.exc_info) if record.exc_info else None,
            }
            self._send(("log", doc))
        except (OSError, ValueError):
            pass  # the front end has gone: nobody to tell
        except Exception:  # noqa: BLE001 - logging must not raise
            self.handleError(record)


def _emit_log(doc: dict[str, Any]) -> None:
    """A worker's log record, through the front end's logger of the same name."""
    record = logging.makeLogRecord(doc)
    logger = logging.getLogger(record.name)
    if logger.isEnabledFor(record.levelno):
        logger.handle(record)


class _Terminated(BaseException):
    """SIGTERM in the worker: shut down in order."""


def _on_sigterm(signum: int, frame: Any) -> None:
    raise _Terminated


def _prefer(nice: int) -> None:
    """Run at ``nice`` when it is above the current priority and allowed; say so when it is not."""
    current = os.getpriority(os.PRIO_PROCESS, 0)
    if nice >= current:
        return
    try:
        os.setpriority(os.PRIO_PROCESS, 0, nice)
    except PermissionError:
        log.info(
            "the station worker runs at nice %d, not %d: no right to raise its priority (root or "
            "CAP_SYS_NICE); under CPU load its cycles may then stretch",
            current,
            nice,
        )


def worker_main(conn: Connection, spec: WorkerSpec) -> None:
    """The worker process: build the station, then serve the front end's calls until the pipe closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the front end, which shuts us down
    signal.signal(signal.SIGTERM, _on_sigterm)
    pipe = _Pipe(conn)
    root = logging.getLogger()
    for handler in list(root.handlers):
        root.removeHandler(handler)
    root.addHandler(_PipeLogHandler(pipe.send))
    root.setLevel(spec.log_level)
    _prefer(spec.nice)
    try:
        host = SessionHost(spec, pipe.send)
    except BaseException as exc:  # noqa: BLE001 - reported to the front end, which raises it
        pipe.send(("failed", _pack_exception(exc), traceback.format_exc()))
        return
    try:
        pipe.send(("ready", host.info()))
        while True:
            message = conn.recv()
            if message[0] == "exit":
                break
            if message[0] == "call":
                threading.Thread(
                    target=_serve_call, args=(host, pipe, *message[1:]), name=f"rpc-{message[2]}", daemon=True
                ).start()
    except (EOFError, OSError):
        why = "the service went away"
    except _Terminated:
        why = "the station worker was terminated (SIGTERM)"
    else:
        why = "the service shut down"
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the shutdown below is the answer to it
    with contextlib.suppress(BaseException):
        host.shutdown(why=why)


def main() -> None:
    """The worker's entry point: ``python -c "import station.worker as w; w.main()" FD``, FD being its
    end of the pipe; the first message is the front end's ``sys.path`` and the :class:`WorkerSpec`."""
    conn = Connection(int(sys.argv[1]))
    try:
        kind, path, spec = conn.recv()
    except EOFError:
        return
    if kind != "start":
        raise SystemExit(f"station worker: expected the start message, got {kind!r}")
    sys.path[:] = path  # the front end's modules (a test's or a benchmark's hooks) import here too
    worker_main(conn, spec)


def _serve_call(
    host: SessionHost, pipe: _Pipe, rid: int, method: str, args: tuple[Any, ...], kwargs: dict[str, Any]
) -> None:
    try:
        value = getattr(host, f"rpc_{method}")(*args, **kwargs)
    except BaseException as exc:  # noqa: BLE001 - the caller gets it
        reply: tuple[Any, ...] = ("reply", rid, False, _pack_exception(exc))
    else:
        reply = ("reply", rid, True, value)
    try:
        pipe.send(reply)
    except (OSError, ValueError):
        return  # the front end has gone
    except Exception as exc:  # noqa: BLE001 - a value that does not pickle
        pipe.send(("reply", rid, False, _pack_exception(SessionError(f"{method}: {exc}"))))


# --------------------------------------------------------------------------- the front end's side


class StationWorker:
    """The front end's handle on the worker: calls, and the mirror of what the worker reports.

    ``on_event(event)`` is called from the handle's reader thread for every event, after ``status``
    has been updated with it; ``on_ended(status)`` when the worker's session failed in a way its runner
    could not record (``status.error`` says why; the record follows once it can be reached).
    """

    def __init__(
        self,
        spec: WorkerSpec,
        *,
        on_event: Callable[[EventRow], None],
        on_exit: Callable[[], None] | None = None,
        on_ended: Callable[[RunnerStatus], None] | None = None,
        start_timeout_s: float = START_TIMEOUT_S,
    ) -> None:
        here, there = Pipe()
        self._on_event = on_event
        self._on_exit = on_exit
        self._on_ended = on_ended
        self._pipe = _Pipe(here)
        self._calls: dict[int, Future[Any]] = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._gone: str | None = None
        self._closing = False
        self.status: RunnerStatus | None = None
        self.prompt: Prompt | None = None
        # a fresh interpreter (not multiprocessing's spawn, which imports the caller's main module again):
        # it inherits the environment and the standard streams; the pipe's other end is its only extra fd
        fd = there.fileno()
        self._process = subprocess.Popen(
            [sys.executable, "-c", "import station.worker as w; w.main()", str(fd)], pass_fds=(fd,)
        )
        there.close()
        try:
            self._pipe.send(("start", list(sys.path), spec))
            deadline = time.monotonic() + start_timeout_s
            while True:
                if not here.poll(max(0.0, deadline - time.monotonic())):
                    raise WorkerError(f"the station worker did not start within {start_timeout_s:.0f} s")
                first = here.recv()
                if first[0] != "log":
                    break
                _emit_log(first[1])
        except (EOFError, OSError) as exc:
            self._kill()
            raise WorkerError(
                f"the station worker exited while starting (exit code {self._process.poll()}): {exc}"
            ) from exc
        except BaseException:
            self._kill()
            raise
        if first[0] == "failed":
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._process.wait(10)
            self._kill()
            raise _unpack_exception(first[1])
        self.info: StationInfo = first[1]
        self._reader = threading.Thread(target=self._read, name="station-worker-reader", daemon=True)
        self._reader.start()

    @property
    def alive(self) -> bool:
        return self._gone is None

    @property
    def pid(self) -> int:
        """The worker's process id."""
        return self._process.pid

    def _kill(self) -> None:
        if self._process.poll() is None:
            self._process.kill()
            self._process.wait(10)
        self._pipe.conn.close()

    def _read(self) -> None:
        conn = self._pipe.conn
        try:
            while True:
                message = conn.recv()
                kind = message[0]
                if kind == "event":
                    self.status = message[2]
                    self._on_event(message[1])
                elif kind == "ended":  # a failure the record could not take (yet): see RunnerStatus.error
                    self.status = message[1]
                    if self._on_ended is not None:
                        self._on_ended(message[1])
                elif kind == "prompt":
                    shown, pid = message[1], message[2]
                    if shown is not None:
                        self.prompt = shown
                    elif self.prompt is not None and self.prompt.id == pid:
                        self.prompt = None
                elif kind == "reply":
                    future = self._calls.pop(message[1], None)
                    if future is not None:
                        if message[2]:
                            future.set_result(message[3])
                        else:
                            future.set_exception(_unpack_exception(message[3]))
                elif kind == "log":
                    _emit_log(message[1])
        except (EOFError, OSError):
            pass
        except Exception:
            log.exception("the station worker's reader failed")
        if not self._closing:
            # the pipe closes while the process exits; its flocks (the station lock) are gone once it has
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._process.wait(30)
        with self._lock:
            self._gone = (
                "the service is shutting down"
                if self._closing
                else f"the station worker process ended (exit code {self._process.poll()}); restart the "
                "service (its session, if any, shows as interrupted)"
            )
            calls, self._calls = self._calls, {}
        self.prompt = None
        for future in calls.values():
            future.set_exception(WorkerError(self._gone))
        if not self._closing:
            log.error("%s", self._gone)
            if self._on_exit is not None:
                self._on_exit()

    def call(self, method: str, *args: Any, timeout_s: float | None = None, **kwargs: Any) -> Any:
        """``SessionHost.rpc_<method>(*args, **kwargs)`` in the worker; its exception is raised here."""
        future: Future[Any] = Future()
        with self._lock:
            if self._gone is not None:
                raise WorkerError(self._gone)
            rid = next(self._ids)
            self._calls[rid] = future
            try:
                self._pipe.send(("call", rid, method, args, kwargs))
            except (OSError, ValueError) as exc:
                self._calls.pop(rid, None)
                raise WorkerError(f"the station worker cannot be reached: {exc}") from exc
        return future.result(timeout_s)

    def close(self, timeout_s: float = 30.0) -> None:
        """Shut the worker down in order (its session interrupted, devices closed) and wait for it."""
        if self._closing:
            return
        if self.alive:
            with contextlib.suppress(WorkerError, TimeoutError, OSError):
                self.call("shutdown", timeout_s, timeout_s=timeout_s + 10)
        self._closing = True
        with contextlib.suppress(OSError, ValueError):
            self._pipe.send(("exit",))
        try:
            self._process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            log.error("the station worker did not exit; terminating it")
            self._process.terminate()
            self._process.wait(10)
        self._reader.join(10)  # the worker's end closed with it: the reader has read to the end
        with contextlib.suppress(OSError):
            self._pipe.conn.close()


__all__ = [
    "ConflictError",
    "NotAvailableError",
    "RunnerStatus",
    "SessionHost",
    "StationInfo",
    "StationWorker",
    "WorkerError",
    "WorkerSpec",
    "worker_main",
]
