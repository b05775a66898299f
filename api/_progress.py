"""The progress of a session the worker is not running: the plan's steps done of its total, from the record.

The worker reports the progress of its latest session with every event; every other session (ended
earlier, imported, or run by another process) used to show ``{done: 0, total: 0}``. The record holds
what is needed: the steps marked ``done`` (the plan's, numbered below the runner's prelude base), and
the plan's step count in the events of the session's first run that reached pre-flight (its
``preflight`` event counts the steps it checked; a run that resumed says so first, in a ``resumed``
event with the steps it skipped and those left).

An ended session changes only when it is resumed (its ``updated_at`` changes then), so its progress is
read once and kept; the sessions list asks for it on every poll.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Sequence

from station.record import EventRow, Record, SessionRow
from station.runner import FINAL_STATES, PRELUDE_BASE, Progress

EARLY_EVENTS = 200
"""How many of a session's first events are read for its plan's step count (a run reaches pre-flight
within its first few events)."""
CACHED = 1024
"""Ended sessions whose progress is kept."""


def planned_steps(events: Sequence[EventRow]) -> int | None:
    """The plan's step count from a session's first events (ascending), None when no run reached
    pre-flight: the first run's ``preflight`` event counts the plan's steps, unless a ``resumed`` event
    comes first (the first run ended before pre-flight), which counts the skipped and the remaining."""
    for e in events:
        if e.type == "resumed":
            return int(e.data.get("skipped_steps", 0)) + int(e.data.get("remaining", 0))
        if e.type == "preflight":
            # ``plan_steps`` leaves out the route to the reference pose (older records: ``steps``)
            return int(e.data.get("plan_steps", e.data.get("steps", 0)))
    return None


class RecordedProgress:
    """Progress of sessions from the record, kept for ended ones (see the module's docstring)."""

    def __init__(self, record: Record) -> None:
        self.record = record
        self._lock = threading.Lock()
        self._cache: OrderedDict[tuple[str, str], Progress] = OrderedDict()

    def of(self, row: SessionRow) -> Progress:
        key = (row.id, row.updated_at.isoformat())
        ended = row.state in FINAL_STATES
        if ended:
            with self._lock:
                cached = self._cache.get(key)
            if cached is not None:
                return cached
        done = sum(1 for s in self.record.steps(row.id) if s.state == "done" and s.index < PRELUDE_BASE)
        total = planned_steps(self.record.events(row.id, limit=EARLY_EVENTS))
        progress = Progress.model_construct(
            done=done, total=max(total, done) if total is not None else done, eta_s=None
        )
        if ended:
            with self._lock:
                self._cache[key] = progress
                while len(self._cache) > CACHED:
                    self._cache.popitem(last=False)
        return progress
