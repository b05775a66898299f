"""The station as a service: one object that owns the record and the station's worker process.

No HTTP here: the routers translate requests into calls of :class:`StationService` and its domain
exceptions into problem details (``api/_errors.py``). Everything it does is the runner's, the record's
and the prompt broker's own work (``station/``), and the devices and the session runner live in a
process of their own (:mod:`station.worker`): the service's clients cost this process's interpreter,
never the runner's. This process reads the record and mirrors what the worker reports (its events, the
runner's state and progress, the open prompt); it fans the events out to streaming clients.

The worker builds the devices once (unconnected) when the service starts; the runner connects and
closes them per session. The station's description comes from the worker's report and the events:
nothing here calls a device.

Reads are cheap while a session runs (clients poll): the running session's row and the session list
come from a cache that every ``state`` event invalidates (a row changes only with its state, and the
list at most a second old for sessions another process imports), the station's description from a
snapshot at most a second old, and the running session's events from an in-memory buffer of the
events the worker reported (the record is read only for what the buffer does not hold).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from api._event_buffer import EventBuffer
from api._measurements import Measurements
from api._progress import RecordedProgress
from api._robot import RobotMirror
from api._scale_calibrations import ScaleCalibrations
from api._session_files import SessionFiles
from api._settings import ServiceSettings
from station.arm_route import ArmPose, ArmStatus, RoutePreview, RouteRejectedError, ToReferenceResult
from station.config import ConfigurationError, StationConfig, load_config
from station.imageio import ImageFileError
from station.kinds import KIND_NAMES
from station.plans import PlanError
from station.prompts import Prompt, PromptAnswer
from station.record import (
    ArchiveRefusedError,
    EventRow,
    Record,
    RecordUnavailableError,
    SessionLockError,
    SessionRow,
    lock_holder,
    station_lock,
)
from station.runner import ACTIVE_STATES, FINAL_STATES, Progress, RunnerState, reconcile
from station.selftest_status import latest_selftest
from station.session import open_record, station_measure_params
from station.vision import field_names
from station.worker import (
    NO_REFERENCE,
    ConflictError,
    NotAvailableError,
    RunnerStatus,
    WorkerClient,
    WorkerError,
    WorkerSpec,
)

log = logging.getLogger(__name__)

CACHE_MAX_AGE_S = 1.0
"""The longest a cached read lags behind the record (a session imported by another process)."""
EVENT_BUFFER = 4096
"""The running session's latest events kept in memory for its event streams."""

ACTIONS = ("pause", "resume", "stop", "abort")
TO_REFERENCE_S = 600.0
"""The longest the service waits for the arm's route to its reference pose (a real arm, slow speed)."""


@dataclass(frozen=True)
class SessionView:
    """A session as the API shows it: the record's row plus the live progress when it runs."""

    row: SessionRow
    progress: Progress


class StationService:
    """The record, and the station's worker process: its devices and at most one running session."""

    def __init__(self, settings: ServiceSettings) -> None:
        self.settings = settings
        self.config: StationConfig | None = load_config(settings.config) if settings.config else None
        self.record: Record = open_record(settings.data, settings.database, self.config)
        self._lock = threading.RLock()
        self._closed = False
        # the read caches (see the module's docstring): ``_generation`` counts the runner's state changes,
        # session creations, imports and actions; a cached read is good while it is unchanged
        self._generation = 0
        self._row_cache: tuple[int, SessionRow] | None = None
        self._list_cache: tuple[int, float, list[SessionRow]] | None = None
        self._station_cache: tuple[tuple[Any, ...], float, dict[str, Any]] | None = None
        self.event_buffer = EventBuffer(EVENT_BUFFER)
        """The worker's latest session's events, and the listeners of every event."""
        self.interrupted_at_start = self._reconcile()
        try:
            self.worker = WorkerClient(
                WorkerSpec(
                    sim=settings.sim,
                    manual_prompts=settings.manual_prompts,
                    config=settings.config,
                    data=self.record.data_dir,
                    database=settings.database,
                    sim_options=dict(settings.sim_options),
                    log_level=min(logging.INFO, logging.getLogger().getEffectiveLevel()),
                    nice=settings.worker_nice,
                ),
                on_event=self._on_event,
                on_exit=self._on_worker_exit,
                on_ended=self._on_session_failed,
            )
        except BaseException:
            self.record.close()
            raise
        self._identities: dict[str, Any] = dict(self.worker.info.identities)
        self._recorded = RecordedProgress(self.record)
        self.measurements = Measurements(
            self.record, lambda: station_measure_params(self.record, self.config)[0], self._grab
        )
        """Frames and uploads measured, and the stored captures shown with their measurement."""
        self.files = SessionFiles(self.record, self.note_import)
        """The record's session files (outcome, report, export, import)."""
        self.scale_calibrations = ScaleCalibrations(self.record.data_dir, lambda: self.running)
        """The station's scale calibration, its history and the revert."""
        self.robot_state = RobotMirror(lambda: self.worker.call("robot_state", timeout_s=60))
        """The robot's state and pose (read by the worker between sessions, see ``api/_robot.py``)."""
        self.robot_state.refresh()

    @property
    def record_is_local(self) -> bool:
        """Whether the record is SQLite's file (its reads take a millisecond), not a database server."""
        return self.record.engine.dialect.name == "sqlite"

    def in_worker(self, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(host, *args)`` in the station's worker process, its value returned here (``fn`` and the
        arguments are pickled: a module-level function). For tests and benchmarks: a simulated
        station's truth is ``host.devices.truth``."""
        return self.worker.call("call", fn, args)

    # ------------------------------------------------------------------ lifecycle

    def _reconcile(self) -> list[str]:
        """Sessions a dead process left active show as ``interrupted`` (when no runner holds the station)."""
        if lock_holder(self.record.data_dir) is not None:
            return []
        try:
            with station_lock(self.record.data_dir, "station serve"):
                return reconcile(self.record)
        except SessionLockError:
            return []
        except RecordUnavailableError as exc:  # the next start reconciles (a runner does it first)
            log.warning("left-over sessions not reconciled: %s", exc)
            return []

    def _on_worker_exit(self) -> None:
        """The worker died (not a shutdown): its session, left active, shows as interrupted."""
        marked = self._reconcile()
        if marked:
            log.error("session(s) %s interrupted: the station worker process ended", ", ".join(marked))
        self._generation += 1

    def _on_session_failed(self, status: RunnerStatus) -> None:
        """The worker's session failed and its record may not say so yet (the worker records it once it
        can): shown ``failed`` with ``status.error`` from now on (:meth:`_view`)."""
        log.error("session %s failed: %s", status.session_id, status.error)
        self._generation += 1

    def close(self, *, timeout_s: float = 30.0) -> None:
        """Shut down (idempotent): a running session is aborted (the robot stopped through its latched
        ``stop()``, the open prompt cancelled), then recorded as ``interrupted`` so that it can be resumed;
        the devices are closed (all in the worker, which then exits)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self.worker.close(timeout_s)
        self.record.close()

    # ------------------------------------------------------------------ events

    def subscribe(self, listener: Callable[[EventRow], None]) -> Callable[[], None]:
        """Call ``listener(event)`` for every event of the worker's sessions (from the worker handle's
        reader thread); returns the unsubscribe."""
        return self.event_buffer.subscribe(listener)

    def _on_event(self, event: EventRow) -> None:
        # the worker handle's reader thread: only quick, non-blocking work here
        if event.type == "connected":
            self._identities = dict(event.data.get("devices", {}))
        elif event.type == "state":
            self._generation += 1
            if event.data.get("state") in FINAL_STATES:
                self.robot_state.refresh()  # a thread of its own: this reader thread delivers the answer
        self.event_buffer.publish(event)

    def events(self, session_id: str | None, *, after_id: int = 0, limit: int = 500) -> list[EventRow]:
        sid = self.record.get_session(session_id).id if session_id is not None else None
        return self.record.events(sid, after_id=after_id, limit=limit)

    def events_after_seq(self, session_id: str, after_seq: int, *, limit: int = 500) -> list[EventRow]:
        """A session's events with ``seq > after_seq`` (its stream resumes by sequence number)."""
        buffered = self.event_buffer.after(session_id, after_seq, limit=limit)
        if buffered is not None:
            return buffered
        return self.record.events(session_id, after_seq=after_seq, limit=limit)

    def buffered_events(self, session_id: str, after_seq: int, *, limit: int = 500) -> list[EventRow] | None:
        """``EventBuffer.after``: no database read (the event streams call this on the event loop)."""
        return self.event_buffer.after(session_id, after_seq, limit=limit)

    def session_ended(self, session_id: str) -> bool | None:
        """Whether the worker's run of ``session_id`` has ended (None: not the worker's latest session)."""
        status = self.worker.status
        if status is None or status.session_id != session_id:
            return None
        return self.running is None

    # ------------------------------------------------------------------ the station

    @property
    def running(self) -> RunnerStatus | None:
        """The worker's session while it has not ended (as of its latest event)."""
        status = self.worker.status
        if status is None or status.state in FINAL_STATES or not self.worker.alive:
            return None
        return status

    def station(self) -> dict[str, Any]:
        """Configuration (secrets redacted), each device's identity and state; never touches a device.
        At most a second old (the station lock's holder, read from its file)."""
        runner = self.running
        key = (
            runner.session_id if runner else None,
            runner.state if runner else None,
            id(self._identities),
            self.robot_state.generation,
        )
        cached = self._station_cache
        now = time.monotonic()
        if cached is not None and cached[0] == key and now - cached[1] < CACHE_MAX_AGE_S:
            return cached[2]
        doc = self._station(runner)
        self._station_cache = (key, now, doc)
        return doc

    def _station(self, runner: RunnerStatus | None) -> dict[str, Any]:
        info = self.worker.info
        busy = runner is not None
        robot = self.robot_state.doc(busy=busy) if "robot" in info.devices else None
        devices: dict[str, Any] = {
            name: {"identity": self._identities.get(name, {}), "state": "in_session" if busy else "idle"}
            for name in info.devices
        }
        if robot is not None:
            # its identity as the latest read gave it (the worker reads it at start: never "?" until the
            # first session), its state as that read found it
            devices["robot"] = {
                "identity": {**devices["robot"]["identity"], **(self.robot_state.identity() or {})},
                "state": robot["state"],
            }
        holder = lock_holder(self.record.data_dir)
        return {
            "name": info.name or "offline",
            "sim": self.settings.sim,
            "manual_prompts": self.settings.manual_prompts,
            "config": info.config_snapshot,
            "devices": devices,
            "data_dir": str(self.record.data_dir),
            "record": self.record.url,
            "session": (
                {"id": runner.session_id, "kind": runner.kind, "state": str(runner.state)} if runner else None
            ),
            "lock": holder,
            "plans": list(KIND_NAMES),
            "worker": {"alive": self.worker.alive, "pid": self.worker.pid, "nice": info.nice},
            "robot": robot,
            "selftest": None if robot is None else latest_selftest(self.record, devices["robot"]["identity"]),
        }

    # ------------------------------------------------------------------ measurement

    # ------------------------------------------------------------------ the arm outside sessions

    def robot(self) -> ArmStatus:
        """Where the arm is against its reference pose, and the route there: a read now (in the worker;
        nothing moves) that ``/station``'s ``robot`` shows too; ConflictError while a session owns the arm,
        NotAvailableError without a robot with a reference pose."""
        doc = self.robot_state.read()
        if doc is None or doc.get("route") is None:
            raise NotAvailableError(NO_REFERENCE)
        return ArmStatus(
            position=ArmPose.model_validate(doc),
            reference_joints_deg=doc["reference_joints_deg"],
            at_reference=doc["at_reference"],
            route=RoutePreview.model_validate(doc["route"]),
        )

    def to_reference(self) -> ToReferenceResult:
        """Take the arm to its reference pose along its route (in the worker, which owns the devices);
        ConflictError while a session runs, RouteRejectedError (nothing moved) when a move fails the
        driver's checks."""
        try:
            done = ToReferenceResult.model_validate(
                self.worker.call("to_reference", timeout_s=TO_REFERENCE_S)
            )
        except (ConflictError, RouteRejectedError):
            raise  # the arm did not move
        except Exception:
            self.robot_state.refresh()  # where a failure on the way left it
            raise
        # read before answering, so that ``/station`` shows the arm at its reference pose with the reply
        with contextlib.suppress(Exception):  # the read's failure is the robot's state in ``/station``
            self.robot_state.read()
        return done

    def acknowledge_stop(self, peer_host: str | None) -> dict[str, Any]:
        """Release the robot's stop latch for a person at the station (``peer_host``, the connection's
        peer, must be loopback: RemoteAcknowledgementError otherwise, nothing released); ConflictError
        while a session owns the arm. ``{"acknowledged", "reason"}``; ``/station`` shows it read again."""
        done: dict[str, Any] = self.worker.call("acknowledge_stop", peer_host)
        with contextlib.suppress(Exception):  # the read's failure is the robot's state in ``/station``
            self.robot_state.read()
        return done

    # ------------------------------------------------------------------ sessions

    def create_session(
        self, kind: str, params: Mapping[str, Any], assignments: Mapping[str, Any] | None = None
    ) -> SessionView:
        """Create and start a session in the worker; it answers once pre-flight has passed
        (PreflightError: nothing moved). ConflictError while another one runs."""
        if kind not in KIND_NAMES:
            raise PlanError(f"unknown session kind {kind!r}; known: {', '.join(KIND_NAMES)}")
        return self._start("create", kind, dict(params), measurement_names(assignments or {}))

    def _start(self, method: str, *args: Any) -> SessionView:
        """Start a session in the worker (``create`` or ``resume``) and show it."""
        if self._closed:
            raise ConflictError("the service is shutting down")
        sid = self.worker.call(method, *args)
        self._generation += 1
        return self.get_session(sid)

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait for the worker's session thread to end (tests, shutdown); True when it has."""
        try:
            done: bool = self.worker.call("wait", timeout_s)
        except WorkerError:
            return True
        return done

    def list_sessions(self, *, limit: int, offset: int) -> tuple[list[SessionView], int]:
        rows = self._session_rows()
        return [self._view(r) for r in rows[offset : offset + limit]], len(rows)

    def _session_rows(self) -> list[SessionRow]:
        """The record's sessions; while the worker runs one, from a cache that its state changes
        invalidate (and at most a second old: another process may import a session meanwhile)."""
        if self.running is None:
            self._list_cache = None
            return self.record.list_sessions()
        generation, now = self._generation, time.monotonic()
        cached = self._list_cache
        if cached is not None and cached[0] == generation and now - cached[1] < CACHE_MAX_AGE_S:
            return cached[2]
        rows = self.record.list_sessions()
        if self._generation == generation:  # no state change while reading: the rows are current
            self._list_cache = (generation, now, rows)
        return rows

    def get_session(self, session_id: str) -> SessionView:
        return self._view(self._session_row(session_id))

    def _session_row(self, session_id: str) -> SessionRow:
        """The record's row; the running session's from a cache its state changes invalidate (its row
        changes only with its state while it runs)."""
        runner = self.running
        if runner is None or runner.session_id != session_id:
            try:
                return self.record.get_session(session_id)
            except RecordUnavailableError:
                # the worker's latest session as last read: its state and error come from the worker
                cached, status = self._row_cache, self.worker.status
                if cached is None or status is None or not cached[1].id == session_id == status.session_id:
                    raise
                return cached[1]
        generation = self._generation
        cached = self._row_cache
        if cached is not None and cached[0] == generation and cached[1].id == session_id:
            return cached[1]
        row = self.record.get_session(session_id)
        now_running = self.running
        if (
            self._generation == generation
            and now_running is not None
            and now_running.session_id == session_id
        ):
            self._row_cache = (generation, row)
        return row

    def _view(self, row: SessionRow) -> SessionView:
        status = self.worker.status
        if status is not None and status.session_id == row.id:
            state = status.state
            if state not in FINAL_STATES and row.state != state and self.worker.alive:
                # the runner's state is set (in memory, under its lock) before the record's: a client that
                # sees the prompt it raised finds the session awaiting the operator; a final state comes
                # from the record, with its error
                row = dataclasses.replace(row, state=str(state))
            elif status.error is not None and row.state in ACTIVE_STATES:
                # it failed where its runner could not record it (the record gone): the worker says so
                row = dataclasses.replace(row, state=str(state), error=status.error)
            if status.progress.total == 0 and status.state not in FINAL_STATES:
                # a run that has not counted its steps yet (a resumed one, before pre-flight): what the
                # record holds, so that its count goes on from where it stopped
                return SessionView(row, self._recorded.of(row))
            return SessionView(row, status.progress)
        return SessionView(row, self._recorded.of(row))

    def act(self, session_id: str, action: str) -> SessionView:
        """pause, resume (also continues an interrupted, stopped, failed or aborted session), stop, abort."""
        if action not in ACTIONS:
            raise PlanError(f"unknown action {action!r}; one of {', '.join(ACTIONS)}")
        row = self.record.get_session(session_id)
        try:
            handled = self.worker.call("act", row.id, action)
        finally:
            self._generation += 1
        if handled:
            return self.get_session(row.id)
        if action == "resume" and row.state in (
            RunnerState.INTERRUPTED,
            RunnerState.STOPPED,
            RunnerState.FAILED,
            RunnerState.ABORTED,
        ):
            return self._start("resume", row.id)
        if row.state in ACTIVE_STATES:
            raise ConflictError(
                f"session {row.id} is {row.state} in another process (the station lock's holder); "
                "control it there"
            )
        raise ConflictError(f"cannot {action} session {row.id}: it is {row.state}")

    # ------------------------------------------------------------------ operator prompts

    def prompt(self) -> Prompt | None:
        """The open operator prompt, as the worker last reported it (no call to the worker)."""
        return self.worker.prompt  # None without a station: nothing asks

    def confirm(self, prompt_id: str, readings: Mapping[str, float] | None, *, by: str) -> PromptAnswer:
        answer: PromptAnswer = self.worker.call("confirm", prompt_id, readings, by)
        self._answered(prompt_id)
        return answer

    def cancel(self, prompt_id: str, *, reason: str, by: str) -> PromptAnswer:
        answer: PromptAnswer = self.worker.call("cancel", prompt_id, reason, by)
        self._answered(prompt_id)
        return answer

    def _answered(self, prompt_id: str) -> None:
        """The prompt is closed: stop showing it now (the worker's report of it follows)."""
        shown = self.worker.prompt
        if shown is not None and shown.id == prompt_id:
            self.worker.prompt = None

    def _grab(self) -> Any:
        """One frame from the camera, grabbed by the worker (ConflictError while a session owns it)."""
        return self.worker.call("grab", timeout_s=60)

    def note_import(self) -> None:
        """A session was imported into the record: the cached reads are stale."""
        self._generation += 1


def measurement_names(values: Mapping[str, Any]) -> dict[str, Any]:
    """``--set`` names, case-insensitive (``TESTWIDTH`` is ``testwidth``); PlanError for an unknown one."""
    try:
        return field_names(values, option="set")
    except ValueError as exc:
        raise PlanError(str(exc)) from None


ImportArchiveError = ArchiveRefusedError
"""An uploaded export archive cannot be imported (HTTP 422 ``bad_archive``)."""


__all__ = [
    "ACTIONS",
    "ConfigurationError",
    "ConflictError",
    "ImageFileError",
    "ImportArchiveError",
    "NotAvailableError",
    "ServiceSettings",
    "SessionView",
    "StationService",
    "WorkerError",
]
