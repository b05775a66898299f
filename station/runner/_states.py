"""A session's states, the runner's errors and progress, and what a session records of the software.

States (``SessionState``)::

    idle -> running <-> awaiting_operator
            running -> pausing -> paused -> running
            running | paused | awaiting_operator -> stopping -> stopped
            any active state -> aborting -> aborted
            any active state -> failed | succeeded
    a session whose process died shows ``interrupted`` (found when the next runner takes the lock)
"""

from __future__ import annotations

import enum
import socket
import threading
from collections import deque
from collections.abc import Sequence
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from station import __version__
from station.plans import Step

PRELUDE_BASE = 1_000_000
"""Step indices of resume preludes start here (plan steps are numbered from 0)."""
EARLY_FAILURE_CAPTURES = 3
"""A session whose first this-many captures all fail to measure stops: something is misconfigured."""


class SessionState(enum.StrEnum):
    """A session's state; the string values are the contract (the record, the CLI's ``--json``, the API)."""

    IDLE = "idle"
    RUNNING = "running"
    PAUSING = "pausing"
    PAUSED = "paused"
    AWAITING_OPERATOR = "awaiting_operator"
    STOPPING = "stopping"
    STOPPED = "stopped"
    ABORTING = "aborting"
    ABORTED = "aborted"
    FAILED = "failed"
    SUCCEEDED = "succeeded"
    INTERRUPTED = "interrupted"


FINAL_STATES = frozenset(
    {
        SessionState.STOPPED,
        SessionState.ABORTED,
        SessionState.FAILED,
        SessionState.SUCCEEDED,
        SessionState.INTERRUPTED,
    }
)
ACTIVE_STATES = frozenset(
    {
        SessionState.RUNNING,
        SessionState.PAUSING,
        SessionState.PAUSED,
        SessionState.AWAITING_OPERATOR,
        SessionState.STOPPING,
        SessionState.ABORTING,
    }
)


class SessionError(RuntimeError):
    """A session cannot be started, resumed or controlled (the message says why and what to do)."""


class PreflightError(SessionError):
    """Pre-flight found problems; nothing moved. ``problems`` lists every one."""

    def __init__(self, problems: Sequence[str]) -> None:
        super().__init__(
            f"pre-flight found {len(problems)} problem(s); nothing moved:\n  - " + "\n  - ".join(problems)
        )
        self.problems = list(problems)


class AbortRequestedError(Exception):
    """Raised in the runner thread when an abort was requested."""


class StopRequestedError(Exception):
    """Raised at a safe point when a stop was requested."""


class Progress(BaseModel):
    """A session's progress: steps done of the plan's total, and the estimated time left (s); the API's
    ``progress`` and the ``step_finished`` event's."""

    model_config = ConfigDict(frozen=True)

    done: int = Field(ge=0)
    total: int = Field(ge=0)
    eta_s: float | None = None

    def to_json(self) -> dict[str, Any]:
        return self.model_dump()


class ProgressCounter:
    """Counts a session's steps as they are done, and their durations for the estimated time left
    (thread-safe: the store thread counts, anyone reads)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.total = 0
        self._done = 0
        self._t_steps: deque[float] = deque(maxlen=20)  # the latest step durations, for the ETA

    def start(self, total: int, *, done: int) -> None:
        """``total`` steps in the plan, ``done`` of them before this run (a resume continues the count)."""
        with self._lock:
            self.total, self._done = total, done

    def step_done(self, step: Step, seconds: float) -> dict[str, Any]:
        """A step is done (a resume prelude's or a route's is not counted); the progress as JSON."""
        with self._lock:
            if step.index < PRELUDE_BASE:
                self._done += 1
            self._t_steps.append(seconds)
        return self.progress().to_json()

    def progress(self) -> Progress:
        with self._lock:
            done, total = self._done, self.total
            eta = None
            if self._t_steps and total:
                per = sum(self._t_steps) / len(self._t_steps)
                eta = round(per * (total - done), 1)
            return Progress.model_construct(done=done, total=total, eta_s=eta)


def software_info() -> dict[str, str]:
    """What a session records of the software (``software``): versions and the host."""
    import platform

    import cv2
    import numpy as np

    return {
        "station": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "opencv": cv2.__version__,
        "host": socket.gethostname(),
    }
