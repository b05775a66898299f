"""The device's end of a pseudo-terminal, as the twins' serving threads use it.

A twin (the C500C controller, the Keyence DL-RS1A) serves its device's dialect on a pty that a real
driver opens with pyserial. :class:`PtyPort` is that end: raw (no echo, no CR translation by the line
discipline: the twin writes exactly its device's bytes), non-blocking, with a wake-up pipe so that
another thread (close, unplug) can interrupt the serving thread's wait. Only the serving thread reads
and writes; ``close`` (the cable pulled) leaves the wake-up pipe, ``dispose`` ends everything.
"""

from __future__ import annotations

import contextlib
import logging
import os
import pty
import select
import threading
import time
import tty

log = logging.getLogger(__name__)


class PtyPort:
    """A raw, non-blocking pty master with a wake-up pipe (see the module notes)."""

    def __init__(self) -> None:
        self.master: int | None = None
        self.slave: int | None = None
        self.path: str | None = None
        self._wake_r, self._wake_w = os.pipe()

    @property
    def is_open(self) -> bool:
        return self.master is not None

    def open(self) -> str:
        """Open a new pty; returns the slave's path (what a driver opens)."""
        master, slave = pty.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self.master, self.slave = master, slave
        self.path = os.ttyname(slave)
        return self.path

    def close(self) -> None:
        """Close the pty (the cable pulled); safe to call twice. The wake-up pipe stays."""
        for fd in (self.master, self.slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self.master = self.slave = None
        self.path = None

    def dispose(self) -> None:
        """Close the pty and the wake-up pipe: the port is done."""
        self.close()
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)

    def wake(self) -> None:
        """Interrupt the serving thread's :meth:`read` (from any thread)."""
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")

    def write(self, data: bytes, stop: threading.Event) -> None:
        """Write all of ``data`` unless ``stop`` is set or the pty goes away (a host gone is no error)."""
        master = self.master
        while data and master is not None and not stop.is_set():
            try:
                data = data[os.write(master, data) :]
            except BlockingIOError:
                select.select([], [master], [], 0.05)
            except OSError as exc:
                log.debug("twin write: %s", exc)
                return

    def read(self, timeout_s: float | None) -> bytes | None:
        """Bytes from the host, or None on timeout, on a wake-up, or while no host has the pty open."""
        master = self.master
        fds = [self._wake_r] if master is None else [master, self._wake_r]
        readable, _, _ = select.select(fds, [], [], timeout_s)
        if self._wake_r in readable:
            with contextlib.suppress(OSError):
                os.read(self._wake_r, 1024)
            return None
        if master is not None and master in readable:
            try:
                return os.read(master, 4096)
            except BlockingIOError:
                return None
            except OSError:  # no slave open (EIO): wait for one
                time.sleep(0.01)
                return None
        return None


__all__ = ["PtyPort"]
