"""The service's events in memory: the latest session's events in order (the event streams resume from
them without a database read) and the listeners every event is handed to."""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable

from station.record import EventRow

log = logging.getLogger(__name__)


class EventBuffer:
    """The last ``size`` events of the worker's latest session, and the event listeners."""

    def __init__(self, size: int) -> None:
        self._recent: deque[EventRow] = deque(maxlen=size)
        self._listeners: list[Callable[[EventRow], None]] = []
        self._lock = threading.Lock()

    def subscribe(self, listener: Callable[[EventRow], None]) -> Callable[[], None]:
        """Call ``listener(event)`` for every event published; returns the unsubscribe."""
        with self._lock:
            self._listeners.append(listener)

        def unsubscribe() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)

        return unsubscribe

    def publish(self, event: EventRow) -> None:
        """Keep ``event`` (a new session's first one clears the buffer) and hand it to every listener
        (outside the lock: a listener may subscribe or unsubscribe)."""
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

    def after(self, session_id: str, after_seq: int, *, limit: int = 500) -> list[EventRow] | None:
        """The events with ``seq > after_seq`` of the latest session, or None when the buffer cannot
        tell (another session, or events older than the buffer's first)."""
        # tuple() copies the deque in one step under the GIL (the reader thread appends meanwhile)
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
