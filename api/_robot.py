"""The robot as the service shows it (``GET /api/v1/station``'s ``robot``): its state and pose from the
start, not only once a session has connected it.

The station worker owns the robot; between sessions it is closed. :class:`RobotMirror` asks the worker
to read it (``SessionHost.rpc_robot_state``: connect, status, position and the route to the reference
pose checked, close; nothing moves) in a thread of its own, so that a read of ``/station`` never waits
for the serial line: when the service starts, when a session ends, after ``to-reference``, and when the
latest read is older than :data:`MAX_AGE_S` while no session runs (someone may have jogged the arm at
its pendant). ``GET /station/robot`` is the same read made at once (:meth:`RobotMirror.read`), which the
mirror keeps too: there is one read of the arm, not two. While a session runs the robot is the
session's: the mirror shows the last read, marked ``in_session``.
"""

from __future__ import annotations

import contextlib
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
SHOWN = (
    "power",
    "homed",
    "latched",
    "joints_deg",
    "commanded_joints_deg",
    "reference_joints_deg",
    "at_reference",
)
"""The keys of a read that ``/station`` shows (besides ``state``, ``read_at`` and ``error``)."""

Reader = Callable[[], dict[str, Any] | None]


class RobotMirror:
    """The latest read of the robot and whether one is under way.

    ``read`` is the worker's read (``SessionHost.rpc_robot_state``'s dict, None without a robot, or an
    exception whose message says what is wrong); ``clock`` is monotonic seconds.
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

    def read(self) -> dict[str, Any] | None:
        """Read the robot now, in this thread, and keep what the read found (its error too); the read's
        dict (None without a robot), or its exception."""
        held = False
        try:
            doc = self._read()
            error = None
        except (ConflictError, SessionLockError) as exc:  # a session (here or elsewhere) has the robot
            doc, error, held = None, str(exc), True
            raise
        except Exception as exc:
            doc, error = None, str(exc) or type(exc).__name__
            log.info("reading the robot failed: %s", error)
            raise
        finally:
            with self._lock:
                if error is None:
                    self._latest, self._absent = doc, doc is None
                self._error, self._held = error, held
                self._read_at = datetime.now(UTC).isoformat()
                self._at = self._clock()
                self.generation += 1
        return doc

    def _read_now(self) -> None:
        with contextlib.suppress(Exception):  # kept by read(): shown as the robot's state and error
            self.read()

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
        doc: dict[str, Any] = {key: (latest or {}).get(key) for key in SHOWN}
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
            doc.update(power=None, homed=None, latched=None, joints_deg=None, commanded_joints_deg=None)
        else:
            state = "idle"
        if in_use or error is not None:
            doc["at_reference"] = None  # while a session moves the arm (or unread), not known here
        doc.update(state=state, read_at=read_at, error=error)
        return doc

    def identity(self) -> dict[str, Any] | None:
        """The identity the latest read gave (model, serial, port, firmware), None before one."""
        with self._lock:
            latest = self._latest
        identity = latest.get("identity") if latest else None
        return dict(identity) if identity else None
