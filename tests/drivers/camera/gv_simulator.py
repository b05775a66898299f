"""Aravis' GigE Vision camera simulator on 127.0.0.1, shared safely by pytest-xdist workers.

Only one simulator fits on loopback, and a GigE camera has one controlling client at a time. So every
test that uses it holds an exclusive file lock for its duration (``exclusive()``); under that lock the
simulator is started if none is running, and the pid is kept in a state file that all workers read.
The worker that started a simulator stops it when its session ends (taking the lock first); a worker
that needs one afterwards starts its own. No lock is held between tests, so workers never wait on each
other's idle time.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import signal
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

log = logging.getLogger(__name__)

PROGRAM = "arv-fake-gv-camera-0.8"
ADDRESS = "127.0.0.1"
SERIAL = "GV02"
DEVICE_ID = f"Aravis-Fake-{SERIAL}"
GVCP_PORT = 3956
START_TIMEOUT_S = 10.0
STOP_TIMEOUT_S = 10.0

_DIR = Path(tempfile.gettempdir())
LOCK_PATH = _DIR / "station-arv-fake-gv.lock"
PID_PATH = _DIR / "station-arv-fake-gv.pid"
LOG_PATH = _DIR / "station-arv-fake-gv.log"


def _is_simulator(pid: int) -> bool:
    """Whether ``pid`` is a live (not zombie) simulator process."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False
    state = stat.rpartition(")")[2].split()[0]
    return state not in {"Z", "X"} and PROGRAM.encode() in cmdline


def _gvcp_port_bound() -> bool:
    """Whether something listens on UDP 127.0.0.1:3956 (the simulator's control port)."""
    wanted = f"0100007F:{GVCP_PORT:04X}"
    with contextlib.suppress(OSError):
        for line in Path("/proc/net/udp").read_text().splitlines()[1:]:
            if line.split()[1] == wanted:
                return True
    return False


class GvSimulator:
    """One worker's handle on the shared simulator."""

    def __init__(self) -> None:
        self._process: subprocess.Popen[bytes] | None = None

    @contextlib.contextmanager
    def exclusive(self) -> Iterator[int]:
        """Hold the simulator for one test; yield its pid (running and answering on 127.0.0.1)."""
        with self._locked():
            yield self._ensure_running()

    def stop(self) -> None:
        """Stop the simulator if this worker started it."""
        process, self._process = self._process, None
        if process is None:
            return
        with self._locked():
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
                try:
                    process.wait(timeout=STOP_TIMEOUT_S)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait(timeout=STOP_TIMEOUT_S)
            if PID_PATH.exists() and PID_PATH.read_text().strip() == str(process.pid):
                PID_PATH.unlink()

    @contextlib.contextmanager
    def _locked(self) -> Iterator[None]:
        with LOCK_PATH.open("a") as handle:
            fcntl.flock(handle, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(handle, fcntl.LOCK_UN)

    def _ensure_running(self) -> int:
        with contextlib.suppress(OSError, ValueError):
            pid = int(PID_PATH.read_text())
            if _is_simulator(pid) and _gvcp_port_bound():
                return pid
        if self._process is not None:  # ours, but it died: reap it before starting another
            self._process.wait(timeout=STOP_TIMEOUT_S)
            self._process = None
        with LOG_PATH.open("ab") as log_file:
            process = subprocess.Popen(
                [PROGRAM, "-i", ADDRESS, "-s", SERIAL],
                stdin=subprocess.DEVNULL,
                stdout=log_file,
                stderr=subprocess.STDOUT,
            )
        self._process = process
        deadline = time.monotonic() + START_TIMEOUT_S
        while not _gvcp_port_bound():
            if process.poll() is not None:
                self._process = None
                raise RuntimeError(
                    f"{PROGRAM} exited with {process.returncode} at start; see {LOG_PATH} "
                    "(is another GigE Vision simulator bound to 127.0.0.1:3956?)"
                )
            if time.monotonic() > deadline:
                raise RuntimeError(f"{PROGRAM} did not bind 127.0.0.1:{GVCP_PORT} within {START_TIMEOUT_S} s")
            time.sleep(0.01)
        PID_PATH.write_text(str(process.pid))
        log.info("started %s (pid %d) on %s", PROGRAM, process.pid, ADDRESS)
        return process.pid

    @staticmethod
    def pause(pid: int) -> None:
        """Freeze the simulator (no frames, no answers) as a stalled camera would be.

        Returns once the process has stopped (SIGSTOP is delivered asynchronously: a loaded machine can
        let it send one more frame's leader after ``kill`` returned) and the packets it had sent have
        had time to reach the receiver and be stamped, so that a grab begun after this finds them old.
        """
        os.kill(pid, signal.SIGSTOP)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            with open(f"/proc/{pid}/stat") as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
            if state in ("T", "t"):
                break
            time.sleep(0.001)
        time.sleep(0.05)

    @staticmethod
    def resume(pid: int) -> None:
        os.kill(pid, signal.SIGCONT)
