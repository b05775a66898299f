"""The operator's control of a running session: pause, resume, stop and abort, asked from any thread and
obeyed by the runner's thread at its safe points (between steps) or, for an abort, at once."""

from __future__ import annotations

import threading
from collections.abc import Callable

from station.runner._journal import Journal
from station.runner._states import (
    FINAL_STATES,
    AbortRequestedError,
    SessionError,
    SessionState,
    StopRequestedError,
)


class SessionControl:
    """The control flags of one session and the states they lead to (written by the ``journal``).

    The lock guards the flags only: it is never held while a listener runs, and nothing under it waits
    for more than a database write.
    """

    def __init__(self, journal: Journal) -> None:
        self.journal = journal
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        self.pausing = False
        self.stopping = False
        self.aborting = False

    def pause(self) -> None:
        """Pause at the next safe point (between steps)."""
        with self._lock:
            if self.journal.state in FINAL_STATES or self.stopping or self.aborting:
                raise SessionError(f"cannot pause a session that is {self.journal.state}")
            self.pausing = True
            self.journal.set_state(SessionState.PAUSING, only_from={SessionState.RUNNING}, wait=False)
            self._cond.notify_all()

    def resume(self) -> None:
        """Continue after a pause."""
        with self._lock:
            state = self.journal.state
            if state not in (SessionState.PAUSED, SessionState.PAUSING):
                raise SessionError(f"cannot resume a session that is {state}; only a paused one")
            self.pausing = False
            self.journal.set_state(SessionState.RUNNING, only_from={SessionState.PAUSING}, wait=False)
            self._cond.notify_all()

    def stop(self) -> None:
        """Stop at the next safe point (nothing when the session has ended or is aborting)."""
        with self._lock:
            if self.journal.state in FINAL_STATES or self.aborting:
                return
            self.stopping = True
            self.journal.set_state_unless_ended(SessionState.STOPPING, wait=False)
            self._cond.notify_all()

    def abort(self) -> bool:
        """Ask for an abort (the state ``aborting`` at once); whether this call asked it (False when the
        session has ended or an abort was asked already)."""
        with self._lock:
            if self.journal.state in FINAL_STATES or self.aborting:
                return False
            self.aborting = True
            self.journal.set_state_unless_ended(SessionState.ABORTING, wait=False)
            self._cond.notify_all()
            return True

    def aborted(self) -> bool:
        return self.aborting

    def wait_for_abort(self, seconds: float) -> bool:
        """Wait ``seconds`` unless an abort comes first; whether it came."""
        with self._lock:
            self._cond.wait_for(lambda: self.aborting, timeout=seconds)
        return self.aborting

    def begin(self) -> bool:
        """The session starts: ``running`` (``stopping`` when a stop came first); False when an abort did."""
        with self._lock:
            if self.aborting:
                return False
            self.journal.set_state(
                SessionState.STOPPING if self.stopping else SessionState.RUNNING, wait=False
            )
            return True

    def safe_point(self, drain: Callable[[], None]) -> None:
        """Between steps: rest while paused; raise when a stop or an abort was asked (``drain()`` first:
        what the last step captured is stored before the session rests or ends)."""
        if self.pausing or self.stopping or self.aborting:
            drain()
        with self._lock:
            self._raise_if_asked()
            if not self.pausing:
                return
            self.journal.set_state(SessionState.PAUSED, wait=False)
            while self.pausing and not (self.stopping or self.aborting):
                self._cond.wait(0.5)
            self._raise_if_asked()
            self.journal.set_state(SessionState.RUNNING, wait=False)

    def _raise_if_asked(self) -> None:
        if self.aborting:
            raise AbortRequestedError()
        if self.stopping:
            raise StopRequestedError()
