"""The stop latch: after a stop, a halt at the controller, an E-stop or a controller error during a
motion, every motion is refused until a person at the station acknowledges it.

In memory it is an event (a motion waiting for its arrival watches it from another thread) and the
reason that set it. With a ``latch_file`` (the station puts it in its data directory) it is also a
small JSON file, written atomically when the latch sets and removed when it is acknowledged, so that
it outlives the process: a new ``station robot`` or a restarted service finds the arm still latched.
Only :class:`station.local_ack.LocalAcknowledgement` releases it (see that module for who can make one).
"""

from __future__ import annotations

import json
import logging
import os
import threading
import time
from pathlib import Path

from station.local_ack import ACKNOWLEDGE_HINT, LocalAcknowledgement, RemoteAcknowledgementError

log = logging.getLogger(__name__)

__all__ = ["StopLatch"]


class StopLatch:
    """The latch's state: ``is_set``, ``reason``; ``set(reason)``, ``acknowledge(ack)``."""

    def __init__(self, latch_file: str | os.PathLike[str] | None = None) -> None:
        self.event = threading.Event()
        self.reason: str | None = None
        self.file = None if latch_file is None else Path(latch_file)
        self._used: set[str] = set()
        self._on_file = False  # whether the file holds this latch (written or read by this process)
        if self.file is not None:
            found = self._read()
            if found is not None:
                self.event.set()
                self.reason = found
                self._on_file = True
                log.warning("the robot's stop is still latched (%s): %s", self.file, found)

    def sync(self) -> None:
        """Follow the latch file, which other processes of this station share (called on every connect).

        A latch this process keeps in the file, whose file is gone, was acknowledged by another process
        at the station (``station robot --config F acknowledge`` at its terminal): released here too. A
        file that appeared was latched by another process: latched here too. Without a file, nothing."""
        if self.file is None:
            return
        found = self._read()
        if found is None and self.event.is_set() and self._on_file:
            log.warning(
                "the stop was acknowledged by another process at the station (its latch file is gone)"
            )
            self.reason = None
            self._on_file = False
            self.event.clear()
        elif found is not None and not self.event.is_set():
            log.warning("the robot's stop was latched by another process (%s): %s", self.file, found)
            self.reason = found
            self._on_file = True
            self.event.set()

    def is_set(self) -> bool:
        return self.event.is_set()

    def set(self, reason: str) -> None:
        """Latch (the first reason is kept until acknowledged); persisted when there is a latch file."""
        if not self.event.is_set() or self.reason is None:
            self.reason = reason
        self.event.set()
        if self.file is not None:
            self._write(self.reason or reason)

    def acknowledge(self, ack: object) -> str | None:
        """Release the latch with a fresh, unused :class:`LocalAcknowledgement`; return the reason it
        had. Raises RemoteAcknowledgementError for anything else (nothing released)."""
        if not isinstance(ack, LocalAcknowledgement):
            raise RemoteAcknowledgementError(
                f"a stop is released only by a local acknowledgement, not by {type(ack).__name__}: "
                + ACKNOWLEDGE_HINT
            )
        if not ack.fresh():
            raise RemoteAcknowledgementError(
                "that acknowledgement is too old: acknowledge again at the station"
            )
        if ack.nonce in self._used:
            raise RemoteAcknowledgementError("that acknowledgement was used already: acknowledge again")
        self._used.add(ack.nonce)
        reason = self.reason
        if self.file is not None:
            try:
                self.file.unlink(missing_ok=True)
            except OSError as exc:
                raise RemoteAcknowledgementError(
                    f"the latch file {self.file} cannot be removed ({exc.strerror or exc}): the stop stays"
                    " latched; check the data directory's permissions"
                ) from exc
        self.reason = None
        self._on_file = False
        self.event.clear()
        log.warning("stop acknowledged at the station (%s %s); it was: %s", ack.source, ack.who, reason)
        return reason

    def _read(self) -> str | None:
        assert self.file is not None
        try:
            doc = json.loads(self.file.read_text(encoding="utf-8"))
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as exc:  # unreadable: latched all the same
            return f"a latch file that cannot be read ({exc})"
        reason = doc.get("reason") if isinstance(doc, dict) else None
        return str(reason) if reason else "a stop (no reason recorded)"

    def _write(self, reason: str) -> None:
        assert self.file is not None
        tmp = self.file.with_name(self.file.name + f".{os.getpid()}.tmp")
        try:
            self.file.parent.mkdir(parents=True, exist_ok=True)
            with tmp.open("w", encoding="utf-8") as f:
                json.dump({"reason": reason, "latched_at": time.time()}, f)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.file)
            self._on_file = True
        except OSError as exc:  # the in-memory latch holds regardless
            log.error(
                "the stop latch could not be written to %s: %s (it holds in this process)", self.file, exc
            )
