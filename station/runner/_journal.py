"""The journal of a session: its persisted state and its events, and their delivery to listeners.

The journal is the one writer of a session's events and state in the record (the runner's thread and its
store thread both report through it) and the one that calls the listeners. Writing is serialised by the
journal's own short lock (a database commit each); listeners are called *outside* every lock, in event
order, by one thread at a time (the deliverer): so a listener that is slow, blocks, or calls back into the
runner from any thread never holds up the runner's control (``abort`` returns at once) and never
deadlocks it.

Delivery: ``emit(..., wait=True)`` (the session's own threads, holding no lock of the runner) returns once
its event was delivered: the thread delivers the queue itself, or waits for the thread that does (a
listener sees a step start before the step's actions run). ``wait=False`` (control calls from other
threads, and anything said with the runner's lock held) queues the event; a helper thread delivers it when
no one else is delivering.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable, Collection
from typing import Any

from station.prompts import PromptEvent
from station.record import EventRow, Record, RecordError
from station.runner._states import ACTIVE_STATES, FINAL_STATES, SessionState

log = logging.getLogger("station.runner")

Listener = Callable[[EventRow], None]
_RUNNING = frozenset({SessionState.RUNNING, SessionState.PAUSING})


class Journal:
    """A session's state (persisted) and events (persisted, then delivered to the listeners in order).

    Parameters
    ----------
    record
        Where the state and the events are written.
    session_id
        The session's id, once it exists in the record (``attach``); nothing is written before.
    """

    def __init__(self, record: Record, session_id: str | None = None) -> None:
        self.record = record
        self.session_id = session_id
        self._state = SessionState.IDLE
        self._write = threading.Lock()  # the record's writes and the queue's order: short, never a listener
        self._listeners: list[Listener] = []
        self._queue: deque[tuple[int, EventRow]] = deque()
        self._queued = 0  # how many events were queued, ever
        self._delivered = 0  # how many of them the listeners have seen
        self._deliverer: threading.Thread | None = None
        self._cond = threading.Condition(threading.Lock())  # the queue's delivery, apart from the writes

    @property
    def state(self) -> SessionState:
        return self._state

    def attach(self, session_id: str) -> None:
        """The session now exists in the record: its events and states are written from here on."""
        self.session_id = session_id

    def subscribe(self, listener: Listener) -> Callable[[], None]:
        """Call ``listener(event)`` for every event (outside the runner's locks); returns the unsubscribe."""
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    # ------------------------------------------------------------------ writing

    def emit(self, kind: str, data: dict[str, Any], *, wait: bool = True) -> None:
        """Persist one event, then deliver it (``wait``: before returning; see the module's notes)."""
        if self.session_id is None:
            return
        with self._write:
            try:
                event = self.record.add_event(self.session_id, kind, data)
            except RecordError as exc:
                log.error("event %s not recorded: %s", kind, exc)
                return
            n = self._enqueue(event)
        self._deliver(n, wait=wait)

    def set_state(
        self,
        state: SessionState,
        *,
        only_from: Collection[SessionState] | None = None,
        error: str | None = None,
        wait: bool = True,
    ) -> bool:
        """Enter ``state`` (persisted, and a ``state`` event), at once or only from one of ``only_from``;
        returns whether it did. A final state is written with its ``error`` (none for a success)."""
        with self._write:
            was = self._state
            if state is was or (only_from is not None and was not in only_from):
                return False
            self._state = state
            if self.session_id is None:
                return True
            final = state in FINAL_STATES
            if not final:
                self.record.set_state(self.session_id, state)
            try:
                event = self.record.add_event(
                    self.session_id, "state", {"state": str(state), "was": str(was)}
                )
            except RecordError as exc:
                log.error("event state %s not recorded: %s", state, exc)
                event = None
            if final:  # the row says it with its error before any listener hears of it
                self.record.set_state(self.session_id, state, error=error)
            n = self._enqueue(event) if event is not None else 0
        if n:
            self._deliver(n, wait=wait)
        return True

    def set_state_unless_ended(self, state: SessionState, *, wait: bool = True) -> bool:
        """``state`` unless the session has not started or has already ended."""
        return self.set_state(state, only_from=ACTIVE_STATES, wait=wait)

    # ------------------------------------------------------------------ delivering

    def _enqueue(self, event: EventRow) -> int:
        with self._cond:
            self._queued += 1
            self._queue.append((self._queued, event))
            return self._queued

    def _deliver(self, n: int, *, wait: bool) -> None:
        me = threading.current_thread()
        with self._cond:
            if self._deliverer is me:  # said by a listener: delivered after the current one, in order
                return
            if self._deliverer is None:
                if wait:
                    self._deliverer = me
                else:
                    self._deliverer = threading.Thread(target=self._deliver_all, name="journal", daemon=True)
                    self._deliverer.start()
                    return
            elif not wait:
                return
            else:
                while self._delivered < n and self._deliverer is not None and self._deliverer is not me:
                    self._cond.wait()
                if self._delivered >= n:
                    return
                if self._deliverer is None:
                    self._deliverer = me
                else:
                    return
        self._deliver_all()

    def _deliver_all(self) -> None:
        """In the deliverer's thread: every queued event to every listener, in order, holding no lock."""
        while True:
            with self._cond:
                if not self._queue:
                    self._deliverer = None
                    self._cond.notify_all()
                    return
                n, event = self._queue.popleft()
            for listener in list(self._listeners):
                try:
                    listener(event)
                except Exception:
                    log.exception("event listener failed")
            with self._cond:
                self._delivered = n
                self._cond.notify_all()

    def flush(self) -> None:
        """Wait until every event written so far has been delivered."""
        with self._cond:
            target = self._queued
        self._deliver(target, wait=True)


def record_prompt(journal: Journal, event: PromptEvent, *, paused: Callable[[], bool], wait: bool) -> None:
    """An operator prompt opened (the session ``awaiting_operator``, then ``prompt_raised``) or closed
    (``prompt_answered``, then the session back to running, or pausing when a pause was asked meanwhile)."""
    p = event.prompt
    if event.kind == "opened":
        journal.set_state(SessionState.AWAITING_OPERATOR, only_from=_RUNNING, wait=wait)
        fields = [f.__dict__ for f in p.fields]
        journal.emit(
            "prompt_raised", {"id": p.id, "kind": p.kind, "message": p.message, "fields": fields}, wait=wait
        )
        return
    a = event.answer
    journal.emit(
        "prompt_answered",
        {
            "id": p.id,
            "outcome": str(a.outcome) if a else None,
            "readings": dict(a.readings) if a else {},
            "by": a.by if a else "",
            "reason": a.reason if a else "",
        },
        wait=wait,
    )
    back = SessionState.PAUSING if paused() else SessionState.RUNNING
    journal.set_state(back, only_from={SessionState.AWAITING_OPERATOR}, wait=False)


def reconcile(record: Record) -> list[str]:
    """Mark sessions left in an active state by a dead process as ``interrupted``; call with the station
    lock held (no live runner can own them then). Returns the ids marked."""
    marked = []
    for s in record.list_sessions():
        if s.state in ACTIVE_STATES:
            record.set_state(s.id, SessionState.INTERRUPTED, error=s.error)
            record.add_event(s.id, "state", {"state": SessionState.INTERRUPTED, "was": s.state})
            marked.append(s.id)
    return marked
