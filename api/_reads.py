"""What the service reads, kept cheap while a session runs (clients poll): the sessions' rows and list,
the station's description, and the running session's events.

The running session's row and the session list come from a cache that every ``state`` event invalidates
(a row changes only with its state, and the list at most a second old for sessions another process
imports), the station's description from a snapshot at most a second old, and the running session's
events from an in-memory buffer of the events the worker reported (the record is read only for what the
buffer does not hold). No HTTP here, and no control: ``api._service`` starts and controls sessions.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from api._event_buffer import EventBuffer
from api._progress import RecordedProgress
from api._robot import RobotMirror
from api._settings import ServiceSettings
from station.kinds import KIND_NAMES
from station.record import EventRow, Record, RecordUnavailableError, SessionRow, lock_holder
from station.runner import ACTIVE_STATES, FINAL_STATES, Progress
from station.selftest_status import latest_selftest
from station.worker import RunnerStatus, WorkerClient

CACHE_MAX_AGE_S = 1.0
"""The longest a cached read lags behind the record (a session imported by another process)."""
EVENT_BUFFER = 4096
"""The running session's latest events kept in memory for its event streams."""


@dataclass(frozen=True)
class SessionView:
    """A session as the API shows it: the record's row plus the live progress when it runs."""

    row: SessionRow
    progress: Progress


class SessionReads:
    """The record's sessions and events, and the station's description, as the worker's reports keep
    them current.

    Parameters
    ----------
    record
        The station's record.
    worker
        The station's worker (its status, its info), once it runs.
    robot_state
        The robot's mirror (``api._robot``).
    settings
        The service's settings (``/station`` shows whether it is a simulation).
    """

    def __init__(
        self,
        record: Record,
        worker: Callable[[], WorkerClient],
        robot_state: RobotMirror,
        settings: ServiceSettings,
    ) -> None:
        self.record = record
        self._worker = worker
        self.robot_state = robot_state
        self.settings = settings
        # ``generation`` counts the runner's state changes, session creations, imports and actions; a
        # cached read is good while it is unchanged
        self.generation = 0
        self._row_cache: tuple[int, SessionRow] | None = None
        self._list_cache: tuple[int, float, list[SessionRow]] | None = None
        self._station_cache: tuple[tuple[Any, ...], float, dict[str, Any]] | None = None
        self.identities: dict[str, Any] = {}
        self.event_buffer = EventBuffer(EVENT_BUFFER)
        """The worker's latest session's events, and the listeners of every event."""
        self._recorded = RecordedProgress(record)

    def forget_station(self) -> None:
        """The station's configuration changed (a teach): ``/station`` is read again."""
        self._station_cache = None

    def changed(self) -> None:
        """A session was created, imported or acted on, or the worker ended: the cached reads are stale."""
        self.generation += 1

    # ------------------------------------------------------------------ events

    def subscribe(self, listener: Callable[[EventRow], None]) -> Callable[[], None]:
        """Call ``listener(event)`` for every event of the worker's sessions (from the worker handle's
        reader thread); returns the unsubscribe."""
        return self.event_buffer.subscribe(listener)

    def on_event(self, event: EventRow) -> None:
        """An event the worker reported (its reader thread: only quick, non-blocking work here)."""
        if event.type == "connected":
            self.identities = dict(event.data.get("devices", {}))
        elif event.type == "state":
            self.generation += 1
            if event.data.get("state") in FINAL_STATES:
                self.robot_state.refresh()  # a thread of its own: this reader thread delivers the answer
        self.event_buffer.publish(event)

    def events(self, session_id: str | None, *, after_id: int = 0, limit: int = 500) -> list[EventRow]:
        """Events after ``after_id`` (station-wide ids), of one session (an id or a prefix) or all."""
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
        status = self._worker().status
        if status is None or status.session_id != session_id:
            return None
        return self.running is None

    def session_state(self, session_id: str) -> str:
        """A session's state as the record has it (an id or a unique prefix)."""
        return self.record.get_session(session_id).state

    def session_id(self, session_id: str) -> str:
        """A session's full id (from an id or a unique prefix); RecordError when there is none."""
        return self.record.get_session(session_id).id

    # ------------------------------------------------------------------ the station

    @property
    def running(self) -> RunnerStatus | None:
        """The worker's session while it has not ended (as of its latest event)."""
        worker = self._worker()
        status = worker.status
        if status is None or status.state in FINAL_STATES or not worker.alive:
            return None
        return status

    def station(self) -> dict[str, Any]:
        """Configuration (secrets redacted), each device's identity and state; never touches a device.
        At most a second old (the station lock's holder, read from its file)."""
        runner = self.running
        key = (
            runner.session_id if runner else None,
            runner.state if runner else None,
            id(self.identities),
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
        worker = self._worker()
        info = worker.info
        busy = runner is not None
        robot = self.robot_state.doc(busy=busy) if "robot" in info.devices else None
        devices: dict[str, Any] = {
            name: {"identity": self.identities.get(name, {}), "state": "in_session" if busy else "idle"}
            for name in info.devices
        }
        if robot is not None:
            # its identity as the latest read gave it (the worker reads it at start: never "?" until the
            # first session), its state as that read found it
            devices["robot"] = {
                "identity": {**devices["robot"]["identity"], **(self.robot_state.identity() or {})},
                "state": robot["state"],
            }
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
            "lock": lock_holder(self.record.data_dir),
            "plans": list(KIND_NAMES),
            "worker": {"alive": worker.alive, "pid": worker.pid, "nice": info.nice},
            "robot": robot,
            "selftest": None if robot is None else latest_selftest(self.record, devices["robot"]["identity"]),
        }

    # ------------------------------------------------------------------ sessions

    def list_sessions(self, *, limit: int, offset: int) -> tuple[list[SessionView], int]:
        rows = self._session_rows()
        return [self._view(r) for r in rows[offset : offset + limit]], len(rows)

    def _session_rows(self) -> list[SessionRow]:
        """The record's sessions; while the worker runs one, from a cache that its state changes
        invalidate (and at most a second old: another process may import a session meanwhile)."""
        if self.running is None:
            self._list_cache = None
            return self.record.list_sessions()
        generation, now = self.generation, time.monotonic()
        cached = self._list_cache
        if cached is not None and cached[0] == generation and now - cached[1] < CACHE_MAX_AGE_S:
            return cached[2]
        rows = self.record.list_sessions()
        if self.generation == generation:  # no state change while reading: the rows are current
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
                cached, status = self._row_cache, self._worker().status
                if cached is None or status is None or not cached[1].id == session_id == status.session_id:
                    raise
                return cached[1]
        generation = self.generation
        cached = self._row_cache
        if cached is not None and cached[0] == generation and cached[1].id == session_id:
            return cached[1]
        row = self.record.get_session(session_id)
        now_running = self.running
        if self.generation == generation and now_running is not None and now_running.session_id == session_id:
            self._row_cache = (generation, row)
        return row

    def _view(self, row: SessionRow) -> SessionView:
        worker = self._worker()
        status = worker.status
        if status is not None and status.session_id == row.id:
            state = status.state
            if state not in FINAL_STATES and row.state != state and worker.alive:
                # the runner's state is set (in memory) before the record's: a client that sees the prompt
                # it raised finds the session awaiting the operator; a final state comes from the record,
                # with its error
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
