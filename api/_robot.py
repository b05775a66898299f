"""The robot as the service shows it (``GET /api/v1/station``'s ``robot``): its state and pose from the
start, not only once a session has connected it.

The station worker owns the robot; between sessions it is closed. :class:`RobotMirror` asks the worker
to read it (``SessionHost.rpc_robot_state``: connect, status and position, close; nothing moves) in a thread
of its own, so that a read of ``/station`` never waits for the serial line: when the service starts,
when a session ends, and when the latest read is older than :data:`MAX_AGE_S` while no session runs
(someone may have jogged the arm at its pendant). While a session runs the robot is the session's: the
mirror shows the last read, marked ``in_session``.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

from station.record import SessionLockError
from station.worker import ConflictError

log = logging.getLogger(__name__)

MAX_AGE_S = 10.0
"""The oldest read shown while no session runs; an older one starts a new read."""
AT_REFERENCE_DEG = 0.01
"""The largest difference of a commanded joint from the reference pose still counted as at it."""

Reader = Callable[[], dict[str, Any] | None]


def at_reference(commanded: list[float] | None, reference: list[float] | None) -> bool | None:
    """Whether every commanded joint is within :data:`AT_REFERENCE_DEG` of the reference pose (None when
    either is unknown)."""
    if not commanded or not reference or len(commanded) != len(reference):
        return None
    return all(
        math.isfinite(c) and abs(c - r) <= AT_REFERENCE_DEG for c, r in zip(commanded, reference, strict=True)
    )


class RobotMirror:
    """The latest read of the robot and whether one is under way.

    ``read()`` is the worker's read (a dict, None without a robot, or an exception whose message says
    what is wrong); ``clock`` is monotonic seconds.
    """

    def __init__(self, read: Reader, *, clock: Callable[[], float] = time.monotonic) -> None:
        self._read = read
        self._clock = clock
        self._lock = threading.Lock()
        self._latest: dict[str, Any] | None = None
        self._error: str | None = None
        self._read_at: str | None = None
        self._at = -math.inf
        self._reading: threading.Thread | None = None
        self._absent = False
        self._held = False
        self.generation = 0
        """Counts the reads that finished (a cache of ``/station`` keys on it)."""

    def refresh(self) -> threading.Thread:
        """Start a read unless one is under way; the thread that reads."""
        with self._lock:
            if self._reading is not None and self._reading.is_alive():
                return self._reading
            thread = threading.Thread(target=self._read_now, name="robot-read", daemon=True)
            self._reading = thread
        thread.start()
        return thread

    def _read_now(self) -> None:
        held = False
        try:
            doc = self._read()
            error = None
        except (ConflictError, SessionLockError) as exc:  # a session (here or elsewhere) has the robot
            doc, error, held = None, str(exc), True
        except Exception as exc:  # noqa: BLE001 - shown as the robot's error; the service goes on
            doc, error = None, str(exc) or type(exc).__name__
            log.info("reading the robot failed: %s", error)
        with self._lock:
            if error is None:
                self._latest, self._absent = doc, doc is None
            self._error, self._held = error, held
            self._read_at = datetime.now(UTC).isoformat()
            self._at = self._clock()
            self.generation += 1

    def doc(self, *, busy: bool) -> dict[str, Any] | None:
        """What ``/station`` shows: None without a robot; else the latest read with ``state``
        (``reading`` before the first read, ``idle``, ``in_session`` while this station's session runs,
        ``busy`` while another process's session holds the station, ``unreachable`` when the read
        failed), ``at_reference``, ``read_at`` (ISO 8601, UTC) and ``error``. An old read starts a new
        one when no session runs."""
        with self._lock:
            latest, error, held = self._latest, self._error, self._held
            read_at, at, absent = self._read_at, self._at, self._absent
        if not busy and self._clock() - at > MAX_AGE_S:
            self.refresh()
        if absent:
            return None
        doc: dict[str, Any] = {
            "power": None,
            "homed": None,
            "joints_deg": None,
            "commanded_joints_deg": None,
            "reference_joints_deg": None,
            **(latest or {}),
        }
        doc.pop("identity", None)
        in_use = busy or held
        if busy:
            state = "in_session"
        elif held:
            state = "busy"  # the last read is shown; a new one follows once the station is free
        elif latest is None and error is None:
            state = "reading"
        elif error is not None:
            state = "unreachable"
            # the pose read before is not where the arm is now
            doc.update(power=None, homed=None, joints_deg=None, commanded_joints_deg=None)
        else:
            state = "idle"
        # while a session moves the arm, whether it is at its reference pose is not known here
        at_ref = None if in_use else at_reference(doc["commanded_joints_deg"], doc["reference_joints_deg"])
        doc.update(state=state, at_reference=at_ref, read_at=read_at, error=error)
        return doc

    def identity(self) -> dict[str, Any] | None:
        """The identity the latest read gave (model, serial, port, firmware), None before one."""
        with self._lock:
            latest = self._latest
        identity = latest.get("identity") if latest else None
        return dict(identity) if identity else None
