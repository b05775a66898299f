"""A simulated C500C controller on a real pseudo-terminal: the twin the robot driver talks to.

The twin owns the master side of a pty (``pty.openpty``); a driver opens the slave path (``port``)
with pyserial exactly as it would open ``/dev/ttyS0``. It echoes what is typed, prints the prompt,
answers in the C500C's dialect (``sim._controller_shell``; drivers/crs_a465/DIALECT.md), moves a
simulated arm in time (``sim._controller_arm``) and injects faults on request (``sim._controller_faults``).

By default it behaves as the firmware does: ``joint`` and ``ready`` give the prompt back at once while
the arm moves on; a motion command typed while another runs is held until that one ends; ``home``
waits; Ctrl-C does not stop a motion (the shell ignores SIGINT: the byte stays in the line being typed
[inferred]); Ctrl-Z halts the robot with the robot server's message. ``motion_blocks=True`` is the
older blocking behaviour (the prompt comes when the motion ends), ``ctrl_c_stops=True`` the older Ctrl-C.

Start one in-process::

    with start_twin(time_scale=100, seed=1) as twin:
        robot = station.config.build("robot", "crs_a465", port=twin.port)
        robot.connect()

or as a process shared by several programs: ``station sim controller`` prints the port path.
"""

from __future__ import annotations

import logging
import os
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sim._controller_arm import Arm, ArmParameters, MotionRecord
from sim._controller_faults import (
    DEFAULT_ERROR_TEXT,
    DEFAULT_SERVO_TEXT,
    Fault,
    FaultKind,
    garble,
    parse_fault,
)
from sim._controller_settings import TwinSettings
from sim._controller_shell import Outcome, Shell
from sim._pty import PtyPort
from station.kinematics import Kinematics

log = logging.getLogger(__name__)

CTRL_C = 0x03
CTRL_E = 0x05
CTRL_Z = 0x1A
SERVER = "/sbin/robotsrv"


class ControllerTwin:
    """The simulated controller: a pty, a shell, an arm, and a server thread between them."""

    def __init__(
        self,
        settings: TwinSettings | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
        **overrides: Any,
    ) -> None:
        base = settings.model_dump() if settings is not None else {}
        self.settings = TwinSettings.model_validate({**base, **overrides})
        s = self.settings
        self.kinematics = Kinematics(joint_limits_deg=s.joint_limits_deg)
        params = ArmParameters(
            max_speed_deg_s=s.max_speed_deg_s,
            accel_deg_s2=s.accel_deg_s2,
            counts_per_deg=s.counts_per_deg,
            repeat_sigma_deg=s.repeat_sigma_deg,
            systematic_deg=s.systematic_deg,
            backlash_deg=s.backlash_deg,
            home_pose_deg=s.home_pose_deg,
            ready_pose_deg=s.ready_pose_deg,
            start_pose_deg=s.start_pose_deg or s.ready_pose_deg,
            homing_extra_s=s.homing_extra_s,
            time_scale=s.time_scale,
            log_limit=s.log_limit,
            settle_deg=s.settle_deg,
            settle_time_s=s.settle_time_s,
        )
        self.arm = Arm(
            params,
            self.kinematics,
            power=s.power,
            homed=s.homed,
            speed_pct=s.speed_pct,
            rng=np.random.default_rng(s.seed),
            clock=clock,
        )
        self.shell = Shell(self.arm, kind=s.shell, app_name=s.app_name)
        self._clock = clock
        self._lock = threading.Lock()
        self._received: deque[str] = deque(maxlen=s.log_limit)
        self._commands_seen = 0
        # [commands left to count, fault]: counted down on every line (or every line the fault is ``on``)
        self._faults: list[list[Any]] = [[f.at, f] for f in s.faults]
        self._pty = PtyPort()
        self._link_dir: tempfile.TemporaryDirectory[str] | None = None
        self._link: str | None = None if s.link in (None, "auto") else s.link
        self._thread: threading.Thread | None = None
        self._closing = threading.Event()
        self._unplug_requested = threading.Event()
        self._replug_requested = threading.Event()
        self._replugged = threading.Event()
        self._plugged = threading.Event()
        self._replug_at: float | None = None
        self._line = bytearray()
        self._inbox = bytearray()
        self._last_was_cr = False
        self._scheduled: tuple[float, str] | None = None  # (monotonic time, robot-server error text)
        self._line_free_at = 0.0  # line_baud: when the last byte sent has left the simulated line

    # ---------------------------------------------------------------- lifecycle

    def start(self) -> ControllerTwin:
        """Open the pty and start serving; returns self."""
        if self._thread is not None:
            return self
        self._open_pty()
        self._thread = threading.Thread(target=self._serve, name=f"crs-twin {self.port}", daemon=True)
        self._thread.start()
        log.info(
            "controller twin on %s (%s shell, time scale %g)",
            self.port,
            self.settings.shell,
            self.settings.time_scale,
        )
        return self

    def close(self) -> None:
        """Stop serving, close the pty and remove the link; safe to call twice."""
        if self._closing.is_set():
            return
        self._closing.set()
        self._pty.wake()
        if self._thread is not None:
            self._thread.join(timeout=10)
            if self._thread.is_alive():
                log.error("controller twin thread did not stop")
        self._remove_link()
        if self._link_dir is not None:
            self._link_dir.cleanup()
        self._pty.dispose()

    def __enter__(self) -> ControllerTwin:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def port(self) -> str:
        """What a driver opens: the stable link when one is kept, else the pty's slave path."""
        if self._link is not None:
            return self._link
        if self._pty.path is None:
            raise RuntimeError("the twin is not started")
        return self._pty.path

    @property
    def pty_path(self) -> str | None:
        """The current pty slave path (None while unplugged)."""
        return self._pty.path

    @property
    def motion_log(self) -> list[MotionRecord]:
        """The last ``log_limit`` moves the arm executed, as commanded."""
        return list(self.arm.motion_log)

    @property
    def received(self) -> list[str]:
        """The last ``log_limit`` command lines received (control bytes kept)."""
        with self._lock:
            return list(self._received)

    # ---------------------------------------------------------------- control from outside

    def inject(self, fault: Fault | str) -> None:
        """Aim ``fault`` at the ``fault.at``-th command line from now."""
        if isinstance(fault, str):
            fault = parse_fault(fault)
        with self._lock:
            self._faults.append([fault.at, fault])

    def set_power(self, on: bool) -> None:
        """Arm power on or off (as the operator would at the controller)."""
        self.arm.set_power(on)

    def unplug(self) -> None:
        """Pull the cable now: the pty disappears."""
        self._unplug_requested.set()
        self._pty.wake()

    def replug(self, timeout_s: float = 5.0) -> None:
        """Plug the cable back: a new pty; :attr:`port` (with a link) stays the same path."""
        self._replugged.clear()
        self._replug_requested.set()
        self._pty.wake()
        if not self._replugged.wait(timeout_s):
            raise RuntimeError("the twin did not come back")

    def wait_plugged(self, timeout_s: float = 5.0) -> bool:
        """Block until the pty is back after a disconnect (True) or ``timeout_s`` passes (False)."""
        return self._plugged.wait(timeout_s)

    @property
    def commands_seen(self) -> int:
        with self._lock:
            return self._commands_seen

    # ---------------------------------------------------------------- pty

    def _open_pty(self) -> None:
        self._pty.open()  # raw: the twin echoes itself
        if self.settings.link is not None:
            self._point_link()
        self._plugged.set()
        log.debug("pty %s", self._pty.path)

    def _point_link(self) -> None:
        assert self._pty.path is not None
        if self._link is None:
            self._link_dir = tempfile.TemporaryDirectory(prefix="crs-twin-")
            self._link = str(Path(self._link_dir.name) / "c500c")
        tmp = f"{self._link}.{os.getpid()}.tmp"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(self._pty.path, tmp)
        os.replace(tmp, self._link)

    def _remove_link(self) -> None:
        if self._link is not None and os.path.islink(self._link):
            os.unlink(self._link)

    def _do_unplug(self, replug_after_s: float | None) -> None:
        log.info("twin: cable pulled%s", "" if replug_after_s is None else f", back in {replug_after_s:g} s")
        self._plugged.clear()
        self._pty.close()
        self._remove_link()
        self._line.clear()
        self._inbox.clear()
        self._replug_at = None if replug_after_s is None else time.monotonic() + replug_after_s

    def _do_replug(self) -> None:
        if not self._pty.is_open:
            self._open_pty()
            log.info("twin: back on %s", self._pty.path)
        self._replug_at = None
        self._replugged.set()

    # ---------------------------------------------------------------- I/O

    def _write(self, text: str) -> None:
        if not self._pty.is_open:
            return
        data = text.encode("latin-1", errors="replace")
        if self.settings.line_baud is not None and data:
            # a byte leaves a serial line 10 bit-times after the previous one: hold it until then
            now = time.monotonic()
            self._line_free_at = max(now, self._line_free_at) + len(data) * 10.0 / self.settings.line_baud
            time.sleep(self._line_free_at - now)
        self._pty.write(data, self._closing)

    def _halt_keys(self) -> set[int]:
        return {CTRL_Z, CTRL_C} if self.settings.ctrl_c_stops else {CTRL_Z}

    def _sleep(self, seconds: float) -> bool:
        """Sleep, watching the line for a halt key; True when halted. Other bytes wait as type-ahead.

        A scheduled robot-server error (fault ``servo``) fires during the sleep and ends it (True).
        """
        deadline = time.monotonic() + seconds
        keys = self._halt_keys()
        while not self._closing.is_set():
            if self._fire_scheduled():
                return True
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            if self._scheduled is not None:
                remaining = min(remaining, max(0.0, self._scheduled[0] - time.monotonic()))
            data = self._pty.read(remaining)
            if data:
                hit = [i for i, b in enumerate(data) if b in keys]
                if hit:
                    self._inbox += data[: hit[0]] + data[hit[0] + 1 :]
                    self._halt(data[hit[0]])
                    return True
                self._inbox += data
            if not self._pty.is_open:
                return False
        return False

    def _halt(self, key: int) -> None:
        """A halt key: stop the arm; Ctrl-Z makes the robot server say so [F]."""
        self.arm.stop()
        if key == CTRL_Z:
            self._write(f"{SERVER}: ^Z detected - halting robot...\r\n")
        else:
            self._write("^C\r\n")

    def _fire_scheduled(self) -> bool:
        """Print a due robot-server error unprompted and stop the arm there; True when one fired."""
        due = self._scheduled
        if due is None or time.monotonic() < due[0]:
            return False
        self._scheduled = None
        self.arm.stop()  # (when the twin fires late, the motion may have ended already)
        self._write(f"{SERVER}: {due[1]} (error code 0x{0x7000 + len(due[1]):x})\r\n")
        return True

    # ---------------------------------------------------------------- server

    def _serve(self) -> None:
        while not self._closing.is_set():
            if self._unplug_requested.is_set():
                self._unplug_requested.clear()
                self._do_unplug(None)
            if self._replug_requested.is_set() or (
                self._replug_at is not None and time.monotonic() >= self._replug_at
            ):
                self._replug_requested.clear()
                self._do_replug()
            timeout = (
                0.2 if self._replug_at is None else max(0.0, min(0.2, self._replug_at - time.monotonic()))
            )
            if self._scheduled is not None:
                timeout = max(0.0, min(timeout, self._scheduled[0] - time.monotonic()))
            data = self._pty.read(timeout)
            self._fire_scheduled()
            if data:
                self._inbox += data
            while self._inbox and self._pty.is_open and not self._closing.is_set():
                byte = self._inbox.pop(0)
                self._on_byte(byte)

    def _on_byte(self, byte: int) -> None:
        echo = self.settings.echo
        if byte == CTRL_Z:
            self._halt(CTRL_Z)
            return
        if byte == CTRL_C and self.settings.ctrl_c_stops:
            self._line.clear()
            self.arm.stop()
            self._write("^C\r\n" + self.shell.prompt)
            return
        if byte == CTRL_E:
            return
        if byte in (0x0D, 0x0A):
            if byte == 0x0A and self._last_was_cr:
                self._last_was_cr = False
                return
            self._last_was_cr = byte == 0x0D
            if echo:
                self._write("\r\n")
            line = self._line.decode("latin-1")
            self._line.clear()
            self._on_line(line)
            return
        self._last_was_cr = False
        if byte in (0x08, 0x7F):
            if self._line:
                self._line.pop()
                if echo:
                    self._write("\b \b")
            return
        if 0x20 <= byte < 0x7F:
            self._line.append(byte)
            if echo:
                self._write(chr(byte))
        elif byte == CTRL_C:  # the shell ignores SIGINT: the byte stays in the line [inferred]
            self._line.append(byte)
            if echo:
                self._write("^C")

    def _take_fault(self, line: str) -> Fault | None:
        """Count ``line`` against every pending fault; the first whose count reaches zero fires."""
        fired: Fault | None = None
        with self._lock:
            for entry in list(self._faults):
                fault: Fault = entry[1]
                if fault.on is not None and not line.strip().lower().startswith(fault.on.strip().lower()):
                    continue
                entry[0] -= 1
                if entry[0] <= 0 and fired is None:
                    self._faults.remove(entry)
                    fired = fault
        return fired

    def _on_line(self, line: str) -> None:
        prompt = self.shell.prompt
        if not line.strip():
            self._write(prompt)
            return
        with self._lock:
            self._commands_seen += 1
            n = self._commands_seen
            self._received.append(line)
        fault = self._take_fault(line)
        log.debug("twin <- %r (command %d%s)", line, n, f", fault {fault.kind.value}" if fault else "")
        if fault is not None and fault.kind is FaultKind.DISCONNECT:
            self._do_unplug(fault.replug_after_s)
            return
        if fault is not None and fault.kind is FaultKind.ERROR:
            outcome = Outcome(lines=(fault.text or DEFAULT_ERROR_TEXT).split("\n"))
        elif fault is not None and not fault.execute:
            outcome = Outcome()
        else:
            if self.shell.is_motion(line) and self.arm.moving() and self._sleep(self.arm.remaining_s()):
                # halted while this command was held behind the previous motion [A]
                self._write(f"{line.split()[0]}: Halt() command invoked\r\n{prompt}")
                return
            outcome = self.shell.execute(line)
        if fault is not None and fault.kind is FaultKind.SERVO and outcome.is_motion and outcome.motion_s > 0:
            text = fault.text or DEFAULT_SERVO_TEXT
            self._scheduled = (time.monotonic() + outcome.motion_s * fault.fraction, text)
        lines = outcome.lines
        if fault is not None and fault.kind is FaultKind.GARBLE:
            lines = garble(lines)
        if fault is not None and fault.kind is FaultKind.SLOW:
            self._sleep(fault.delay_s)
        if fault is not None and fault.kind is FaultKind.DROP:
            return
        for text in lines:
            self._write(text + "\r\n")
        blocks = outcome.is_motion and (self.settings.motion_blocks or outcome.waits) and outcome.motion_s > 0
        halted = blocks and self._sleep(outcome.motion_s)
        if not halted:
            after = (
                garble(outcome.after)
                if fault is not None and fault.kind is FaultKind.GARBLE
                else outcome.after
            )
            for text in after:
                self._write(text + "\r\n")
        self._write(prompt)


def start_twin(**options: Any) -> ControllerTwin:
    """Start a twin with :class:`TwinSettings` ``options``; ``port`` is the path to open. Close it after."""
    return ControllerTwin(**options).start()


__all__ = [
    "ControllerTwin",
    "Fault",
    "FaultKind",
    "MotionRecord",
    "TwinSettings",
    "parse_fault",
    "start_twin",
]
