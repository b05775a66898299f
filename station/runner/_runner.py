"""The session runner: control and lifecycle of one session (see the package's notes)."""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from station.compute import ComputeError, MeasureBackend
from station.config import StationDevices
from station.devices import DeviceError, MotionStoppedError, OperatorCancelledError
from station.plans import Plan, PlanContext, PlanError, Step
from station.plans._gates import verdict
from station.plans._recorded import FRAMES_PER_ATTEMPT
from station.prompts import PromptEvent
from station.record import EventRow, Record, RecordError, SessionRow, station_lock
from station.runner._actions import ActionExecutor, step_moves
from station.runner._control import SessionControl
from station.runner._devices import SessionDevices
from station.runner._journal import Journal, reconcile, record_prompt
from station.runner._outcome import analyse, captures_of, write_scale_calibration
from station.runner._preflight import find_problems, route_to_reference
from station.runner._resume import create_session, plan_context, session_steps
from station.runner._states import (
    AbortRequestedError,
    PreflightError,
    Progress,
    ProgressCounter,
    SessionError,
    SessionState,
    StopRequestedError,
)
from station.runner._store import StepRun, StorePipeline
from station.scale_preflight import ScalePreflight
from station.selftest_status import attach_to_session, robot_identity
from station.table_content import place_for_session
from station.vision import MeasureParams

log = logging.getLogger("station.runner")

_RUNNING = frozenset({SessionState.RUNNING, SessionState.PAUSING})


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
        self.counter = ProgressCounter()
        self._run = 0  # how many times this session was resumed: captures of a resumed run carry it
        self._aborted_as = SessionState.ABORTED  # or interrupted (``abort(resumable=True)``)
        self._thread: threading.Thread | None = None  # the one running the session (``run``)
        self.journal = Journal(record, resume_session.id if resume_session else None)
        self.control = SessionControl(self.journal)
        self.hold = SessionDevices(devices, self.journal)
        self.store = StorePipeline(
            record, self.journal, self.measure_params, scale_calibration, self.counter.step_done
        )
        self.error: str | None = None
        self.results: dict[str, Any] | None = None
        self._scale = ScalePreflight(
            devices, plan, self.measure_params, scale_calibration, self.journal.emit, plan_params=params
        )

    # ------------------------------------------------------------------ observation

    def progress(self) -> Progress:
        return self.counter.progress()

    @property
    def session_id(self) -> str | None:
        return self.journal.session_id

    @property
    def state(self) -> SessionState:
        return self.journal.state

    def subscribe(self, listener: Callable[[EventRow], None]) -> Callable[[], None]:
        """Call ``listener(event)`` for every event of this session, in order, outside the runner's locks
        (from the thread that reported it, or the one delivering the journal's events then)."""
        return self.journal.subscribe(listener)

    # ------------------------------------------------------------------ control

    def pause(self) -> None:
        """Pause at the next safe point (between steps)."""
        self.control.pause()

    def resume(self) -> None:
        """Continue after a pause."""
        self.control.resume()

    def stop(self) -> None:
        """Finish the step, return the arm to the reference pose, close the devices: ``stopped``."""
        self.control.stop()

    def abort(self, reason: str = "aborted by the operator", *, resumable: bool = False) -> None:
        """Stop the robot now (latched), cancel the open prompt, move nothing more: ``aborted``, or
        ``interrupted`` when ``resumable`` (the service shutting down: the session is to be resumed).

        Nothing here waits for a listener of the runner's events: the state is written, the stop sent,
        the prompt cancelled, whatever the listeners are doing.
        """
        if not self.control.abort():
            return
        if resumable:
            self._aborted_as = SessionState.INTERRUPTED
        self.error = self.error or reason
        self.hold.stop_now()
        self.hold.cancel_prompt(reason)

    # ------------------------------------------------------------------ running

    def create(self) -> SessionRow:
        """Create the session in the record (state ``idle``) without running it."""
        if self.session_id is not None:
            return self.record.get_session(self.session_id)
        row = create_session(
            self.record,
            self.plan,
            self.params,
            devices=self.devices,
            measure_params=self.measure_params,
            scale_calibration=self.scale_calibration,
            config_snapshot=self._config_snapshot,
            station=self._station,
        )
        self.journal.attach(row.id)
        return row

    def start(self) -> threading.Thread:
        """Run in a new thread; returns it (join it, or watch ``state``)."""
        thread = threading.Thread(target=self._run_quietly, name=f"runner-{self.plan.name}", daemon=True)
        thread.start()
        return thread

    def _run_quietly(self) -> None:
        try:
            self.run()
        except Exception:
            log.exception("session runner ended with an error")

    def run(self) -> SessionState:
        """Run the session to its end; returns the final state once every listener has heard it. Raises
        ``SessionLockError`` when another session holds the station (nothing is created or moved then)."""
        data_dir = Path(self.record.data_dir)
        self._thread = threading.current_thread()
        with station_lock(data_dir, self.session_id or "new") as held:
            reconcile(self.record)
            sid = self.create().id
            unsubscribe = None
            if self.devices is not None:
                unsubscribe = self.devices.broker.subscribe(self._on_prompt)
            try:
                final = self._run_session(sid)
            except BaseException:  # Ctrl-C, SystemExit, an error before it ran: recorded (the arm stopped)
                held.release()
                self._finish(SessionState.ABORTED if self.control.aborting else SessionState.FAILED)
                raise
            finally:
                if unsubscribe is not None:
                    unsubscribe()
            # the station is free before anyone can see the outcome: whoever sees it may start the next
            # session at once (that one waits for this final state to be recorded before it reconciles)
            held.release()
            self._finish(final)
            return final

    def _run_session(self, sid: str) -> SessionState:
        ctx = plan_context(
            self.plan,
            sid,
            record=self.record,
            devices=self.devices,
            measure_params=self.measure_params,
            jobs=self.jobs,
            compute=self.compute,
            cancelled=self.control.aborted,
        )
        final = SessionState.FAILED
        if not self.control.begin():
            return SessionState.ABORTED
        try:
            with contextlib.ExitStack() as stack:
                stack.callback(lambda: self.store.close(self.error))
                self.store.open()
                try:
                    steps, prelude = self._steps(ctx)
                    self.hold.connect(stack, aborted=self.control.aborted)
                    route, problems = route_to_reference(
                        self.plan, self.params, ctx, self.devices, self.record, prelude
                    )
                    self._place_on_table(route + prelude + steps, problems)
                    self._preflight(route + prelude + steps, problems)
                    for step in route + prelude + steps:
                        self.control.safe_point(self.store.drain)
                        self._run_step(sid, step, ctx)
                        self._check_progress(sid, ctx)
                    self.store.drain()
                    self.store.check()
                    final = SessionState.SUCCEEDED
                except StopRequestedError:
                    if "robot" in self.plan.needs:
                        self.hold.return_to_reference()
                    self.store.drain()
                    self.store.check()
                    final = SessionState.STOPPED
                finally:
                    if final is SessionState.STOPPED:
                        self.journal.set_state_unless_ended(SessionState.STOPPING)
            self._analyse(ctx, keep_going=final is not SessionState.SUCCEEDED)
            if final is SessionState.SUCCEEDED and self.results is None:
                final = SessionState.FAILED
            gates = verdict(self.results)
            if final is SessionState.SUCCEEDED and gates is not None:
                # a result that fails a gate is kept and shown, marked failed: never a success
                final = SessionState.FAILED
                self.error = gates
                self.journal.emit("error", {"message": gates, "type": "GateError"})
        except (AbortRequestedError, MotionStoppedError, OperatorCancelledError) as exc:
            if self.control.aborting:
                final = SessionState.ABORTED
                self.hold.reread_position("abort")
            else:
                final = SessionState.FAILED
                self._fail(exc)
            self._analyse(ctx, keep_going=True)
        except (DeviceError, RecordError, PlanError, SessionError, ComputeError, OSError, ValueError) as exc:
            final = SessionState.ABORTED if self.control.aborting else SessionState.FAILED
            self._fail(exc)
            self._analyse(ctx, keep_going=True)
        except BaseException as exc:  # KeyboardInterrupt, SystemExit: stop the arm; run() records it
            self._fail(exc)
            raise
        return final

    def _finish(self, final: SessionState) -> None:
        sid = self.session_id
        assert sid is not None
        if self.results is not None:
            self.record.set_results(sid, self.results)
        if final is SessionState.SUCCEEDED:
            write_scale_calibration(
                self.plan, self.record, self.results, self.journal
            )  # before the state says succeeded: a client then finds it
        if final is SessionState.ABORTED:
            final = self._aborted_as
        error = None if final is SessionState.SUCCEEDED else self.error
        self.journal.set_state(final, error=error)
        self.journal.flush()  # every listener has heard the end before run() returns
        log.info("session %s %s", sid, final)

    def _fail(self, exc: BaseException) -> None:
        message = str(exc) or type(exc).__name__
        if self.error is None or not self.control.aborting:
            self.error = message
        log.error("session failed: %s", message)
        self.journal.emit("error", {"message": message, "type": type(exc).__name__})
        self.hold.stop_after(exc)

    def _analyse(self, ctx: PlanContext, *, keep_going: bool) -> None:
        done = analyse(self.plan, self.params, ctx, self.record, self.journal, keep_going=keep_going)
        self.results = done.results
        if done.error is not None:
            self.error = done.error
        elif self.results is not None:
            assert ctx.session_id is not None
            identity = robot_identity(self.devices)
            self.results = attach_to_session(self.results, self.record, ctx.session_id, identity)

    # ------------------------------------------------------------------ steps

    def _steps(self, ctx: PlanContext) -> tuple[list[Step], list[Step]]:
        planned = session_steps(
            self.plan, self.params, ctx, self.record, self.journal, resumed=self._resume is not None
        )
        self._run = planned.run
        # progress counts the plan's steps over the whole session: a resumed run continues the count
        # (a resume prelude re-establishes the set-up; its steps are not the plan's)
        self.counter.start(planned.planned, done=planned.planned - len(planned.steps))
        return planned.steps, planned.prelude

    def _check_progress(self, sid: str, ctx: PlanContext) -> None:
        """A plan's live gates (``check_progress``): once the step is stored and measured, the plan may
        stop the session at once (``GateError``) when what it measured cannot be right."""
        check = getattr(self.plan, "check_progress", None)
        if check is None and not self._scale.pending:
            return
        self.store.drain()
        self.store.check()
        captures = captures_of(self.plan, self.params, self.record, sid)
        self._scale.first_capture(captures)  # the scale check, when pre-flight did not see the crossing
        if check is not None:
            check(self.params, ctx, captures)

    def _place_on_table(self, steps: list[Step], found: list[str]) -> None:
        """What the plan needs on the X-Y table, there before the scale check grabs a frame
        (``station.table_content``). Before the operator is asked for it, the checks that need no frame:
        a session that cannot run asks nobody for anything (and the request that started it is refused)."""

        def checked() -> None:
            self._report(steps, find_problems(steps, self.devices, found))

        place_for_session(
            self.plan, self.params, self.devices, self.record, self.journal.emit, before_asking=checked
        )

    def _preflight(self, steps: list[Step], found: list[str]) -> None:
        """Every problem at once, before anything moves (``station.runner._preflight``)."""
        if self.devices is not None:
            found = [*found, *self._scale.before_motion()]  # the camera model and distance against the groove
        problems = find_problems(steps, self.devices, found)
        self._report(steps, problems, always=True)

    def _report(self, steps: list[Step], problems: list[str], *, always: bool = False) -> None:
        """The ``preflight`` event (when ``always`` or there are problems); ``PreflightError`` on problems."""
        if not (always or problems):
            return
        planned = self.counter.total
        # ``steps``: every step checked (the route and a resume's prelude included); ``plan_steps``: the
        # plan's over the whole session, which progress counts
        self.journal.emit("preflight", {"problems": problems, "steps": len(steps), "plan_steps": planned})
        if problems:
            raise PreflightError(problems)

    def _run_step(self, sid: str, step: Step, ctx: PlanContext) -> None:
        """Run the step's actions here; its captures are stored, measured and the step finished by the
        store thread, in order, while the next step's motions run (the arm never waits for the disk).
        A step is ``done`` in the record only once everything it captured is stored and measured."""
        self.store.check()
        t0 = time.monotonic()
        self.record.begin_step(sid, step.index, step.name, {**step.meta, **self._run_meta()})
        self.journal.emit("step_started", {"index": step.index, "name": step.name})
        # frame indices of a step's n-th attempt start at n x FRAMES_PER_ATTEMPT (a resumed step never
        # overwrites or deletes what an interrupted attempt captured); a step's captures count up from there
        earlier = self.record.captures(sid, step_index=step.index)
        first = (
            (max(c.frame_index for c in earlier) // FRAMES_PER_ATTEMPT + 1) * FRAMES_PER_ATTEMPT
            if earlier
            else 0
        )
        run = StepRun(step, first, t0)
        executor = ActionExecutor(
            self.devices,
            ctx,
            self.measure_params,
            self.journal,
            aborted=self.control.aborted,
            wait_for_abort=self.control.wait_for_abort,
            positions=lambda: self.counter.total,
            run_meta=self._run_meta,
            prompt_timeout_s=getattr(self.params, "prompt_timeout_s", None),
        )
        try:
            executor.run(run, before_action=self.store.check)
        except BaseException as exc:
            # what was grabbed before the failure is still stored (nothing captured is lost)
            self.store.submit(sid, run, failed=str(exc) or type(exc).__name__)
            self.store.drain()
            if isinstance(exc, DeviceError) and step_moves(step):
                self.hold.reread_position("motion error")
            raise
        self.store.submit(sid, run)

    def _run_meta(self) -> dict[str, int]:
        """``{"run": n}`` for the n-th resumed run of a session (nothing for its first: unchanged)."""
        return {"run": self._run} if self._run else {}

    def _on_prompt(self, event: PromptEvent) -> None:
        """The devices' operator prompts: the session awaits the operator while one is open (said from the
        runner's thread when it opens the prompt, so that a client that sees the prompt finds the session
        waiting on it; from whoever answers it otherwise, which never waits for a listener)."""
        record_prompt(
            self.journal,
            event,
            paused=lambda: self.control.pausing,
            wait=threading.current_thread() is self._thread,
        )
