"""The station as a service: one object that owns the record, the devices and the running session.

No HTTP here: the routers translate requests into calls of :class:`StationService` and its domain
exceptions into problem details (``api/_errors.py``). Everything it does is the runner's, the record's
and the prompt broker's own work (``station/``); it only holds the one runner of this process, builds
its parameters the way ``station run`` does, and fans the runner's events out to streaming clients.

Devices are built once (unconnected) when the service starts; the runner connects and closes them
per session. While a session runs, the station's description comes from a cached snapshot: nothing
here calls a robot method then.

Reads are cheap while a session runs (clients poll; the runner shares the process and its GIL): the
running session's row and the session list come from a cache that every ``state`` event of the runner
invalidates (a row changes only with its state, and the list at most a second old for sessions another
process imports), the station's description from a snapshot at most a second old, and the running
session's events from an in-memory buffer of the events the runner reported (the record is read only
for what the buffer does not hold).
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import logging
import threading
import time
import zipfile
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from station.batch import FileResult
from station.config import (
    ConfigurationError,
    StationConfig,
    StationDevices,
    load_config,
    open_sim_station,
    open_station,
)
from station.imageio import ImageFileError, ImageLimits, decode_image
from station.plans import PLAN_NAMES, PlanError, get_plan, parse_params
from station.prompts import Prompt, PromptAnswer
from station.record import (
    EventRow,
    Record,
    RecordError,
    SessionLockError,
    SessionRow,
    lock_holder,
    station_lock,
)
from station.resources import SessionOutcome
from station.runner import (
    ACTIVE_STATES,
    FINAL_STATES,
    PreflightError,
    Progress,
    RunnerState,
    SessionError,
    SessionRunner,
    reconcile,
)
from station.session import open_record, save_scale_calibration, session_measure_params
from station.vision import MeasurementError, MeasureParams, measure

log = logging.getLogger(__name__)

CACHE_MAX_AGE_S = 1.0
"""The longest a cached read lags behind the record (a session imported by another process)."""
EVENT_BUFFER = 4096
"""The running session's latest events kept in memory for its event streams."""

ACTIONS = ("pause", "resume", "stop", "abort")


class ConflictError(SessionError):
    """The request does not fit the session's or the station's state (HTTP 409)."""


class NotAvailableError(SessionError):
    """The station has no such device or feature in this configuration (HTTP 409)."""


@dataclass
class ServiceSettings:
    """What ``station serve`` was given."""

    sim: bool = False
    manual_prompts: bool = False
    config: Path | None = None
    data: Path | None = None
    database: str | None = None
    host: str = "127.0.0.1"
    port: int = 8465
    sim_options: dict[str, Any] = field(default_factory=dict)
    """Extra ``build_sim_station`` options (tests: seed, time scale)."""


@dataclass(frozen=True)
class SessionView:
    """A session as the API shows it: the record's row plus the live progress when it runs."""

    row: SessionRow
    progress: Progress


class StationService:
    """The record, the station's devices and at most one running session of this process."""

    def __init__(self, settings: ServiceSettings) -> None:
        self.settings = settings
        self.config: StationConfig | None = load_config(settings.config) if settings.config else None
        self.record: Record = open_record(settings.data, settings.database, self.config)
        self.devices: StationDevices | None = None
        try:
            if settings.sim:
                self.devices = open_sim_station(operator=not settings.manual_prompts, **settings.sim_options)
            elif self.config is not None:
                self.devices = open_station(self.config)
        except BaseException:
            self.record.close()
            raise
        self._lock = threading.RLock()
        self._runner: SessionRunner | None = None
        self._thread: threading.Thread | None = None
        self._listeners: list[Callable[[EventRow], None]] = []
        self._closed = False
        self._identities: dict[str, Any] = self.devices.identities() if self.devices is not None else {}
        # the read caches (see the module's docstring): ``_generation`` counts the runner's state changes,
        # session creations, imports and actions; a cached read is good while it is unchanged
        self._generation = 0
        self._row_cache: tuple[int, SessionRow] | None = None
        self._list_cache: tuple[int, float, list[SessionRow]] | None = None
        self._station_cache: tuple[tuple[Any, ...], float, dict[str, Any]] | None = None
        self._config_snapshot: dict[str, Any] | None = None
        self._recent: deque[EventRow] = deque(maxlen=EVENT_BUFFER)
        self.interrupted_at_start = self._reconcile()

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

    def close(self, *, timeout_s: float = 30.0) -> None:
        """Shut down (idempotent): a running session is aborted (the robot stopped through its latched
        ``stop()``, the open prompt cancelled), then recorded as ``interrupted`` so that it can be resumed;
        the devices are closed."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        runner, thread = self._runner, self._thread
        if runner is not None and thread is not None and thread.is_alive():
            sid = runner.session_id
            log.warning("shutting down: session %s is interrupted (the robot is stopped)", sid)
            runner.abort("the service shut down")
            thread.join(timeout_s)
            if sid is not None and not thread.is_alive():
                with contextlib.suppress(RecordError):
                    self.record.set_state(
                        sid, RunnerState.INTERRUPTED, error="the service shut down during the session"
                    )
                    self.record.add_event(
                        sid, "state", {"state": str(RunnerState.INTERRUPTED), "was": str(runner.state)}
                    )
        if self.devices is not None:
            self.devices.close_owned()
        self.record.close()

    # ------------------------------------------------------------------ events

    def subscribe(self, listener: Callable[[EventRow], None]) -> Callable[[], None]:
        """Call ``listener(event)`` for every event of this process's sessions (from the runner's thread)."""
        with self._lock:
            self._listeners.append(listener)

        def unsubscribe() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)

        return unsubscribe

    def _on_event(self, event: EventRow) -> None:
        # the runner's thread, under the runner's lock: only quick, non-blocking work here
        if event.type == "connected":
            self._identities = dict(event.data.get("devices", {}))
        elif event.type == "state":
            self._generation += 1
        recent = self._recent
        if recent and recent[-1].session_id != event.session_id:
            recent.clear()
        recent.append(event)
        with self._lock:
            listeners = list(self._listeners)
        for listener in listeners:
            try:
                listener(event)
            except Exception:
                log.exception("event listener failed")

    def events(self, session_id: str | None, *, after_id: int = 0, limit: int = 500) -> list[EventRow]:
        sid = self.record.get_session(session_id).id if session_id is not None else None
        return self.record.events(sid, after_id=after_id, limit=limit)

    def events_after_seq(self, session_id: str, after_seq: int, *, limit: int = 500) -> list[EventRow]:
        """A session's events with ``seq > after_seq`` (its stream resumes by sequence number)."""
        buffered = self.buffered_events(session_id, after_seq, limit=limit)
        if buffered is not None:
            return buffered
        return self.record.events(session_id, after_seq=after_seq, limit=limit)

    def buffered_events(self, session_id: str, after_seq: int, *, limit: int = 500) -> list[EventRow] | None:
        """The events with ``seq > after_seq`` from the in-memory buffer of this process's latest session,
        or None when the buffer cannot tell (another session, or events older than the buffer's first).
        No database read: the event streams call this on the event loop."""
        # tuple() copies the deque in one step under the GIL (the runner's thread appends meanwhile)
        snapshot = tuple(self._recent)
        if not snapshot or snapshot[0].session_id != session_id:
            return None
        start = after_seq + 1 - snapshot[0].seq
        if start < 0:
            return None
        out = list(snapshot[start : start + limit])
        if out and out[0].seq != after_seq + 1:  # the buffer is contiguous; if not, ask the record
            return None
        return out

    def session_ended(self, session_id: str) -> bool | None:
        """Whether this process's runner of ``session_id`` has ended (None: not this process's session)."""
        runner = self._runner
        if runner is None or runner.session_id != session_id:
            return None
        return runner.state in FINAL_STATES

    # ------------------------------------------------------------------ the station

    @property
    def running(self) -> SessionRunner | None:
        runner = self._runner
        return runner if runner is not None and runner.state not in FINAL_STATES else None

    def station(self) -> dict[str, Any]:
        """Configuration (secrets redacted), each device's identity and state; never touches a device.
        At most a second old (the station lock's holder, read from its file)."""
        runner = self.running
        key = (id(runner), runner.state if runner is not None else None, id(self._identities))
        cached = self._station_cache
        now = time.monotonic()
        if cached is not None and cached[0] == key and now - cached[1] < CACHE_MAX_AGE_S:
            return cached[2]
        doc = self._station(runner)
        self._station_cache = (key, now, doc)
        return doc

    def _station(self, runner: SessionRunner | None) -> dict[str, Any]:
        config = self.devices.config if self.devices is not None else self.config
        if self._config_snapshot is None and config is not None:
            self._config_snapshot = config.snapshot()
        busy = runner is not None
        devices: dict[str, Any] = {}
        for name in ("robot", "camera", "table", "distance_sensor"):
            present = self.devices is not None and getattr(self.devices, name) is not None
            if not present:
                continue
            devices[name] = {
                "identity": self._identities.get(name, {}),
                "state": "in_session" if busy else "idle",
            }
        holder = lock_holder(self.record.data_dir)
        return {
            "name": config.name if config is not None else "offline",
            "sim": self.settings.sim,
            "manual_prompts": self.settings.manual_prompts,
            "config": self._config_snapshot,
            "devices": devices,
            "data_dir": str(self.record.data_dir),
            "record": self.record.url,
            "session": (
                {"id": runner.session_id, "kind": runner.plan.name, "state": str(runner.state)}
                if runner
                else None
            ),
            "lock": holder,
            "plans": list(PLAN_NAMES),
        }

    # ------------------------------------------------------------------ measurement

    def measure_image(
        self,
        data: bytes,
        params: Mapping[str, Any],
        *,
        name: str = "upload",
        limits: ImageLimits | None = None,
    ) -> dict[str, Any]:
        """The ``station measure --json`` object for an uploaded image (``ok`` false for a failed
        measurement). ImageFileError for a file that cannot be decoded; PlanError for bad parameters."""
        try:
            mp = MeasureParams.model_validate(dict(params))
        except ValueError as exc:
            raise PlanError(f"measurement parameters: {exc}") from exc
        loaded = decode_image(data, name=name, limits=limits)
        bits = (
            loaded.significant_bits
            if loaded.significant_bits and 8 <= loaded.significant_bits <= 16
            else None
        )
        try:
            result = FileResult(name, measurement=measure(loaded.image, mp, significant_bits=bits))
        except MeasurementError as exc:
            result = FileResult(name, error=exc.message, code=exc.code)
        return result.to_json()

    def snapshot_png(self, *, overlay: bool = False) -> bytes:
        """One frame from the camera as PNG (optionally with the measurement drawn); ConflictError while
        a session owns the camera."""
        from api._overlay import overlay_png

        with self._lock:
            if self.running is not None:
                raise ConflictError(
                    "a session owns the camera: its latest capture is at /api/v1/sessions/{id}/latest.png"
                )
            if self.devices is None:
                raise NotAvailableError("this service has no station (start it with --sim or --config)")
            holder = lock_holder(self.record.data_dir)
            if holder is not None:
                raise SessionLockError(str(self.record.data_dir / "station.lock"), holder)
            camera = self.devices.camera
            camera.connect()
            try:
                frame = camera.grab()
            finally:
                camera.close()
        result = self._measure_array(frame.image) if overlay else None
        return overlay_png(frame.image, result)

    def _measure_array(self, image: Any) -> dict[str, Any]:
        mp, _ = session_measure_params(self.record, "repeatability", {}, self.config, {})
        try:
            return measure(image, mp).to_json()
        except MeasurementError as exc:
            return {"ok": False, "error": exc.message, "code": exc.code}

    def latest_capture_png(self, session_id: str, *, overlay: bool = True) -> bytes:
        """The session's latest stored capture with its measurement drawn (the live view in a session)."""
        from api._overlay import overlay_png

        row = self.record.get_session(session_id)
        captures = self.record.captures(row.id)
        if not captures:
            raise ConflictError(f"session {row.id} has no capture yet")
        cap = captures[-1]
        image = self.record.load_image(cap)
        result = None
        if overlay:
            found = [m for m in self.record.measurements(row.id) if m.capture_id == cap.id]
            result = found[-1].result if found else None
        return overlay_png(image, result)

    # ------------------------------------------------------------------ sessions

    def create_session(
        self, kind: str, params: Mapping[str, Any], assignments: Mapping[str, Any] | None = None
    ) -> SessionView:
        """Create and start a session in a thread; ConflictError while another one runs."""
        if kind not in PLAN_NAMES:
            raise PlanError(f"unknown session kind {kind!r}; known: {', '.join(PLAN_NAMES)}")
        plan = get_plan(kind)
        plan_params = parse_params(plan, dict(params))
        if plan.needs and self.devices is None:
            raise NotAvailableError(
                f"a {kind} session drives hardware, and this service has no station: start it with --sim "
                "or --config FILE"
            )
        assignments = measurement_names(assignments or {})
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
                jobs=1,
            )
        )

    def _station_name(self) -> str:
        if self.devices is not None:
            return self.devices.config.name
        return self.config.name if self.config is not None else "default"

    def _start(self, runner: SessionRunner) -> SessionView:
        with self._lock:
            if self._closed:
                raise ConflictError("the service is shutting down")
            current = self.running
            if current is not None:
                raise ConflictError(
                    f"session {current.session_id} ({current.plan.name}) is {current.state}: one session "
                    "at a time; wait for it to end, or stop or abort it first"
                )
            holder = lock_holder(self.record.data_dir)
            if holder is not None:
                raise SessionLockError(str(self.record.data_dir / "station.lock"), holder)
            runner.subscribe(self._on_event)
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
            self._generation += 1
            thread = threading.Thread(target=self._run, args=(runner,), name="service-session", daemon=True)
            self._thread = thread
            thread.start()
        # the answer waits for pre-flight (devices connected, every motion checked; nothing moved yet), so
        # that out-of-limit targets are refused here, and shows the session under way
        while not checked.wait(0.05) and thread.is_alive():
            pass
        unsubscribe()
        if problems:
            thread.join()
            raise PreflightError(problems)
        assert runner.session_id is not None
        return SessionView(self.record.get_session(runner.session_id), runner.progress())

    def _run(self, runner: SessionRunner) -> None:
        try:
            runner.run()
        except SessionLockError as exc:
            log.error("session %s could not start: %s", runner.session_id, exc)
            if runner.session_id is not None:
                self.record.set_state(runner.session_id, RunnerState.FAILED, error=str(exc))
            return
        except Exception:
            log.exception("session %s ended with an error", runner.session_id)
            return
        if runner.session_id is not None:
            with contextlib.suppress(RecordError, OSError, ValueError):
                save_scale_calibration(self.record, self.record.get_session(runner.session_id))

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait for this process's session thread to end (tests, shutdown); True when it has."""
        thread = self._thread
        if thread is None:
            return True
        thread.join(timeout_s)
        return not thread.is_alive()

    def list_sessions(self, *, limit: int, offset: int) -> tuple[list[SessionView], int]:
        rows = self._session_rows()
        return [self._view(r) for r in rows[offset : offset + limit]], len(rows)

    def _session_rows(self) -> list[SessionRow]:
        """The record's sessions; while this process runs one, from a cache that its state changes
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
            return self.record.get_session(session_id)
        generation = self._generation
        cached = self._row_cache
        if cached is not None and cached[0] == generation and cached[1].id == session_id:
            return cached[1]
        row = self.record.get_session(session_id)
        if self._generation == generation and self.running is runner:
            self._row_cache = (generation, row)
        return row

    def _view(self, row: SessionRow) -> SessionView:
        runner = self._runner
        if runner is not None and runner.session_id == row.id:
            state = runner.state
            if state not in FINAL_STATES and row.state != state:
                # the runner's state is set (in memory, under its lock) before the record's: a client that
                # sees the prompt it raised finds the session awaiting the operator; a final state comes
                # from the record, with its error
                row = dataclasses.replace(row, state=str(state))
            return SessionView(row, runner.progress())
        done = (
            len([s for s in self.record.steps(row.id) if s.state == "done"])
            if row.state in ACTIVE_STATES
            else 0
        )
        return SessionView(row, Progress(done, 0, None)) if done else SessionView(row, Progress(0, 0, None))

    def act(self, session_id: str, action: str) -> SessionView:
        """pause, resume (also continues an interrupted, stopped, failed or aborted session), stop, abort."""
        if action not in ACTIONS:
            raise PlanError(f"unknown action {action!r}; one of {', '.join(ACTIONS)}")
        row = self.record.get_session(session_id)
        runner = self._runner
        if runner is not None and runner.session_id == row.id and runner.state not in FINAL_STATES:
            try:
                getattr(runner, action)()
            except SessionError as exc:
                raise ConflictError(str(exc)) from exc
            finally:
                self._generation += 1
            return self.get_session(row.id)
        if action == "resume" and row.state in (
            RunnerState.INTERRUPTED,
            RunnerState.STOPPED,
            RunnerState.FAILED,
            RunnerState.ABORTED,
        ):
            return self._resume(row)
        if row.state in ACTIVE_STATES:
            raise ConflictError(
                f"session {row.id} is {row.state} in another process (the station lock's holder); "
                "control it there"
            )
        raise ConflictError(f"cannot {action} session {row.id}: it is {row.state}")

    def _resume(self, row: SessionRow) -> SessionView:
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
            )
        )

    # ------------------------------------------------------------------ operator prompts

    def _broker_or_none(self) -> Any:
        return self.devices.broker if self.devices is not None else None

    def prompt(self) -> Prompt | None:
        broker = self._broker_or_none()
        return broker.current() if broker is not None else None

    def confirm(self, prompt_id: str, readings: Mapping[str, float] | None, *, by: str) -> PromptAnswer:
        broker = self._broker_or_none()
        if broker is None:
            raise NotAvailableError("this service has no station, so no operator prompts")
        answer: PromptAnswer = broker.confirm(prompt_id, readings, by=by)
        return answer

    def cancel(self, prompt_id: str, *, reason: str, by: str) -> PromptAnswer:
        broker = self._broker_or_none()
        if broker is None:
            raise NotAvailableError("this service has no station, so no operator prompts")
        answer: PromptAnswer = broker.cancel(prompt_id, reason=reason, by=by)
        return answer

    # ------------------------------------------------------------------ results, reports, export

    def results(self, session_id: str) -> SessionOutcome:
        """``station run --json``'s object for the session."""
        return SessionOutcome.of(self.record.get_session(session_id))

    def report_dir(self, session_id: str) -> Path:
        """The session's report folder, written now if absent or older than the session's last change."""
        from station.commands.sessions import report_document
        from station.reporting import write_report

        row = self.record.get_session(session_id)
        if row.state in ACTIVE_STATES:
            raise ConflictError(f"session {row.id} is {row.state}: its report is written once it has ended")
        folder = self.record.data_dir / "reports" / row.id
        stamp = folder / ".written"
        if not stamp.exists() or stamp.read_text() != row.updated_at.isoformat():
            write_report(report_document(row), folder)
            stamp.write_text(row.updated_at.isoformat())
        return folder

    def export_zip(self, session_id: str) -> bytes:
        import tempfile

        row = self.record.get_session(session_id)
        with tempfile.TemporaryDirectory() as tmp:
            out = self.record.export_session(row.id, Path(tmp) / row.id)
            buf = io.BytesIO()
            with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
                for path in sorted(out.rglob("*")):
                    if path.is_file():
                        zf.write(path, Path(row.id) / path.relative_to(out))
            return buf.getvalue()

    def import_zip(self, data: bytes, *, max_bytes: int) -> SessionRow:
        import tempfile

        try:
            zf = zipfile.ZipFile(io.BytesIO(data))
        except zipfile.BadZipFile as exc:
            raise ImportArchiveError(f"not a zip archive: {exc}") from exc
        with zf, tempfile.TemporaryDirectory() as tmp:
            total = 0
            root = Path(tmp).resolve()
            for info in zf.infolist():
                total += info.file_size
                target = (root / info.filename).resolve()
                if not target.is_relative_to(root):
                    raise ImportArchiveError(f"archive entry {info.filename!r} points outside the archive")
                if total > max_bytes:
                    raise ImportArchiveError(f"the archive unpacks to more than {max_bytes // 2**20} MiB")
            zf.extractall(root)
            folders = [p.parent for p in root.rglob("session.json")]
            if len(folders) != 1:
                raise ImportArchiveError(
                    f"the archive must hold one exported session (one session.json), found {len(folders)}"
                )
            row = self.record.import_session(folders[0])
            self._generation += 1
            return row


def measurement_names(values: Mapping[str, Any]) -> dict[str, Any]:
    """``--set`` names, case-insensitive (``TESTWIDTH`` is ``testwidth``); PlanError for an unknown one."""
    names = {n.lower(): n for n in MeasureParams.model_fields}
    out: dict[str, Any] = {}
    for key, value in values.items():
        name = names.get(key.lower())
        if name is None:
            raise PlanError(f"unknown measurement parameter {key!r}; known: {', '.join(sorted(names))}")
        out[name] = value
    return out


class ImportArchiveError(RecordError):
    """An uploaded export archive cannot be imported (HTTP 422)."""


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
]
