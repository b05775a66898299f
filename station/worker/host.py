"""The worker side: :class:`SessionHost`, which owns the station's devices in the worker process and runs
one session at a time (see the package's notes)."""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from collections.abc import Callable, Mapping
from typing import Any

from station.arm_route import max_step_of
from station.compute import ComputeSpec, open_backend
from station.plans import Plan
from station.prompts import PromptAnswer, PromptBroker, PromptEvent
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
    SessionError,
    SessionRunner,
    SessionState,
)
from station.session import SessionStart
from station.worker._arm import acknowledge_arm, arm_to_reference, read_arm
from station.worker._common import (
    DEVICE_NAMES,
    NO_REFERENCE,
    RECORD_RETRY_S,
    ConflictError,
    NotAvailableError,
    RunnerStatus,
    StationInfo,
    WorkerSpec,
)
from station.worker._teach import ArmTasks, with_taught

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- the worker's side


class SessionHost(ArmTasks):
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
                if self.config is not None:  # the lab's file: its taught values, not the sim's truth
                    self.devices.config = with_taught(self.devices.config, self.config)
                    self.devices.rebuild_robot()  # its sensor mount is the one the keep-out carries
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

    def rpc_info(self) -> StationInfo:
        """What the front end mirrors, as it is now (a teach rewrote the configuration)."""
        return self.info()

    def subscribe(self, listener: Callable[[EventRow], None]) -> None:
        """Also call ``listener(event)`` in the worker for every event (benchmarks' meters)."""
        self._listeners.append(listener)

    def _on_event(self, runner: SessionRunner, event: EventRow) -> None:
        # the thread delivering the journal's events, holding no lock of the runner (station.runner._journal)
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

        def station_given(plan: Plan) -> None:
            if plan.needs and self.devices is None:
                raise NotAvailableError(
                    f"a {kind} session drives hardware, and this service has no station: start it with "
                    "--sim or --config FILE"
                )

        # PlanError naming the plans (the service checked the kind first), or the field
        start = SessionStart.new(self.record, kind, params, self.config, assignments, check=station_given)
        return self._start(self._runner_of(start))

    def rpc_resume(self, session_id: str) -> str:
        """Continue an interrupted, stopped, failed or aborted session of the record."""
        start = SessionStart.resume(self.record, session_id)
        if start.plan.needs and self.devices is None:
            assert start.previous is not None
            raise NotAvailableError(
                f"session {start.previous.id} drives hardware; start the service with --sim or --config"
            )
        return self._start(self._runner_of(start))

    def _runner_of(self, start: SessionStart) -> SessionRunner:
        return start.runner(
            self.record, devices=self.devices, station=self._station_name(), compute=self.compute
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
                elif e.type == "prompt_raised" or (e.type == "state" and e.data.get("state") in FINAL_STATES):
                    checked.set()  # ended, or a person is asked first (what to put on the table)

            unsubscribe = runner.subscribe(on_event)
            runner.create()
            self._runner = runner
            thread = threading.Thread(target=self._run, args=(runner,), name="session", daemon=True)
            self._thread = thread
            thread.start()
        # the answer waits for pre-flight (devices connected, every motion checked; nothing moved yet), so
        # that out-of-limit targets are refused with the request, and shows the session under way; or, when
        # the operator is asked first (checks that need no frame passed), shows it awaiting the operator
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
            SessionState.FAILED,
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
                self.record.set_state(sid, SessionState.FAILED, error=status.error)
                event = self.record.add_event(
                    sid, "state", {"state": str(SessionState.FAILED), "was": row.state}
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
        """Wait for an ended (or aborting) session's thread to finish: it publishes its final state before
        it lets go of the devices and the station lock, and a read of a device right then would find the
        station busy (an aborting session's record may already say ``aborted``)."""
        thread, runner = self._thread, self._runner
        ending = (*FINAL_STATES, SessionState.ABORTING)
        if thread is not None and runner is not None and runner.state in ending:
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
            raise ConflictError(f"the arm is {self._motion}: {what} once it has finished")
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
        self._settle()
        with self._lock:
            robot = self._idle_robot("read it")
            if robot is None:
                return None
            return read_arm(robot, self.devices.reference_joints_deg, self._max_step())

    def rpc_acknowledge_stop(self, peer_host: str | None) -> dict[str, Any]:
        """Release the robot's stop latch for a person at the station: the request came from ``peer_host``
        (the connection's peer address), which must be loopback (RemoteAcknowledgementError otherwise:
        nothing released). ``{"acknowledged": whether a stop was latched, "reason": what latched it}``."""
        with self._lock:
            robot = self._idle_robot("acknowledge its stop")
            if robot is None:
                raise NotAvailableError("this station has no robot: there is no stop to acknowledge")
            return acknowledge_arm(robot, peer_host)

    def rpc_to_reference(self) -> dict[str, Any]:
        """Take the arm to the station's reference pose along its route (``station.arm_route``), every move
        checked before the first is sent (RouteRejectedError: nothing moved); what it did, as JSON."""
        with self._lock:
            robot = self._idle_robot("move it")
            if robot is None or self.devices.reference_joints_deg is None:
                raise NotAvailableError(NO_REFERENCE)
            self._moving, self._motion = True, "on its way to its reference pose"
        try:
            with station_lock(self.record.data_dir, "to-reference"):
                result = arm_to_reference(robot, self.devices.reference_joints_deg, self._max_step())
        finally:
            with self._lock:
                self._moving = False
        log.info("the arm is at its reference pose after %d move(s)", len(result.moves))
        return result.model_dump(mode="json")

    def _max_step(self) -> float:
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
            runner.abort(f"{why} during the session", resumable=True)
            thread.join(timeout_s)
            if sid is not None and not thread.is_alive() and runner.state not in FINAL_STATES:
                # its runner could not record its end (the record gone a moment): interrupted all the same
                with contextlib.suppress(RecordError):
                    self.record.set_state(sid, SessionState.INTERRUPTED, error=f"{why} during the session")
                    event = self.record.add_event(
                        sid, "state", {"state": str(SessionState.INTERRUPTED), "was": str(runner.state)}
                    )
                    progress = runner.progress()
                    status = RunnerStatus(sid, runner.plan.name, SessionState.INTERRUPTED, progress)
                    with contextlib.suppress(OSError, ValueError):
                        self._send(("event", event, status))
        if self.devices is not None:
            self.devices.close_owned()
        self.compute.close()
        self.record.close()
