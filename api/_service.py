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

Its collaborators, each with one job: ``reads`` (``api._reads``: the sessions' rows, the station's
description and the running session's events, cached while a session runs), ``files`` (the record's
session files), ``measurements``, ``scale_calibrations`` and ``robot_state``; the routers get each of them
by a FastAPI dependency (``api._deps``) and never reach into the record. This module starts, controls
and answers: sessions, the arm outside sessions, the operator's prompts.
"""

from __future__ import annotations

import contextlib
import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any

from api._measurements import Measurements
from api._reads import SessionReads, SessionView
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
    Record,
    RecordUnavailableError,
    SessionLockError,
    lock_holder,
    station_lock,
)
from station.runner import ACTIVE_STATES, SessionState, reconcile
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

ACTIONS = ("pause", "resume", "stop", "abort")
TO_REFERENCE_S = 600.0
"""The longest the service waits for the arm's route to its reference pose (a real arm, slow speed)."""


class StationService:
    """The record, and the station's worker process: its devices and at most one running session."""

    def __init__(self, settings: ServiceSettings) -> None:
        self.settings = settings
        self.config: StationConfig | None = load_config(settings.config) if settings.config else None
        self.record: Record = open_record(settings.data, settings.database, self.config)
        self._lock = threading.RLock()
        self._closed = False
        self.robot_state = RobotMirror(lambda: self.worker.call("robot_state", timeout_s=60))
        """The robot's state and pose (read by the worker between sessions, see ``api/_robot.py``)."""
        self.reads = SessionReads(self.record, lambda: self.worker, self.robot_state, settings)
        """The sessions, the station and the events as clients read them (``api._reads``)."""
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
                on_event=self.reads.on_event,
                on_exit=self._on_worker_exit,
                on_ended=self._on_session_failed,
            )
        except BaseException:
            self.record.close()
            raise
        self.reads.identities = dict(self.worker.info.identities)
        self.measurements = Measurements(
            self.record, lambda: station_measure_params(self.record, self.config)[0], self._grab
        )
        """Frames and uploads measured, and the stored captures shown with their measurement."""
        self.files = SessionFiles(self.record, self.note_import)
        """The record's session files (outcome, report, export, import)."""
        self.scale_calibrations = ScaleCalibrations(self.record.data_dir, lambda: self.reads.running)
        """The station's scale calibration, its history and the revert."""
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

    def config_changed(self) -> None:
        """A teach rewrote the configuration the worker's devices use: ``/station`` shows it from now on
        (the worker's snapshot is taken again)."""
        self.worker.info = self.worker.call("info", timeout_s=30)
        self.reads.forget_station()

    def _on_worker_exit(self) -> None:
        """The worker died (not a shutdown): its session, left active, shows as interrupted."""
        marked = self._reconcile()
        if marked:
            log.error("session(s) %s interrupted: the station worker process ended", ", ".join(marked))
        self.reads.changed()

    def _on_session_failed(self, status: RunnerStatus) -> None:
        """The worker's session failed and its record may not say so yet (the worker records it once it
        can): shown ``failed`` with ``status.error`` from now on (``api._reads``)."""
        log.error("session %s failed: %s", status.session_id, status.error)
        self.reads.changed()

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
        self.reads.changed()
        return self.get_session(sid)

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait for the worker's session thread to end (tests, shutdown); True when it has."""
        try:
            done: bool = self.worker.call("wait", timeout_s)
        except WorkerError:
            return True
        return done

    def get_session(self, session_id: str) -> SessionView:
        return self.reads.get_session(session_id)

    def act(self, session_id: str, action: str) -> SessionView:
        """pause, resume (also continues an interrupted, stopped, failed or aborted session), stop, abort."""
        if action not in ACTIONS:
            raise PlanError(f"unknown action {action!r}; one of {', '.join(ACTIONS)}")
        row = self.record.get_session(session_id)
        try:
            handled = self.worker.call("act", row.id, action)
        finally:
            self.reads.changed()
        if handled:
            return self.get_session(row.id)
        if action == "resume" and row.state in (
            SessionState.INTERRUPTED,
            SessionState.STOPPED,
            SessionState.FAILED,
            SessionState.ABORTED,
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
        self.reads.changed()


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
