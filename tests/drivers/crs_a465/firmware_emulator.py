"""A second, independent emulator of the C500C system shell, written from the firmware's formats alone.

It shares no code with the twin (``sim.controller``): its tables, armstat report, error and halt texts
are typed here from the firmware's format strings (DIALECT.md), and its motion is the firmware's
timing: ``joint`` and ``ready`` give the prompt back at once while the arm moves on (linearly, for
``duration_s``); a motion typed while another runs is held until that one ends; ``home`` waits.
Ctrl-Z halts the arm (``/sbin/robotsrv: ^Z detected - halting robot...``); other control bytes stay in
the line being typed, as a raw terminal keeps them. Per-command faults: ``replace`` (print these lines
instead of running), ``drop`` (echo, then silence), ``garble`` (run, then print noise).
"""

from __future__ import annotations

import os
import pty
import select
import threading
import time
import tty

READY = (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)
COUNTS = (400000 / 360,) * 3 + (200000 / 360,) * 3
AXES = "          Axis 1/7   Axis 2/8     Axis 3     Axis 4     Axis 5     Axis 6"
WORLD_AXES = "          X/TrackX   Y/TrackY          Z      Z-Rot      Y-Rot      X-Rot"


def _row(label: str, values: list[str]) -> str:
    return f"{label:<8}" + " ".join(f"{v:>10}" for v in values)


class FirmwareEmulator:
    """A pty that answers as the C500C system shell does; ``path`` is what a driver opens."""

    def __init__(self, *, duration_s: float = 0.3, power: bool = True) -> None:
        self.duration_s = duration_s
        self.power = power
        self.replace: dict[str, list[str]] = {}
        self.drop: set[str] = set()
        self.garble: set[str] = set()
        self.lines: list[str] = []  # every line received, control bytes kept
        self.control_bytes: list[int] = []  # halt keys received
        self.halted = 0
        self._lock = threading.Lock()
        self._start = list(READY)
        self._end = list(READY)
        self._t0 = 0.0
        self._duration = 0.0
        self.master, self.slave = pty.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    # ---------------------------------------------------------------- the arm

    def _fraction(self) -> float:
        if self._duration <= 0.0:
            return 1.0
        return min(1.0, (time.monotonic() - self._t0) / self._duration)

    def joints(self) -> list[float]:
        with self._lock:
            f = self._fraction()
            return [a + f * (b - a) for a, b in zip(self._start, self._end, strict=True)]

    def moving(self) -> bool:
        with self._lock:
            return self._fraction() < 1.0

    def _move_to(self, target: list[float]) -> None:
        while self.moving():  # a second motion is held until the first ends
            time.sleep(0.005)
        with self._lock:
            self._start, self._end = self.joints_unlocked(), target
            self._t0, self._duration = time.monotonic(), self.duration_s

    def joints_unlocked(self) -> list[float]:
        f = self._fraction()
        return [a + f * (b - a) for a, b in zip(self._start, self._end, strict=True)]

    def _halt(self) -> None:
        with self._lock:
            here = self.joints_unlocked()
            self._start, self._end, self._duration = here, here, 0.0
            self.halted += 1

    # ---------------------------------------------------------------- replies

    def _table(self, title: str) -> list[str]:
        q = [round(v, 3) for v in self.joints()]
        pulses = [round(v * c) for v, c in zip(q, COUNTS, strict=True)]
        return [
            f"{title} :",
            "",
            AXES,
            _row("PULSES", [f"{p:+d}" for p in pulses]),
            _row("", ["+0", "+0"]),
            "",
            AXES,
            _row("JOINTS", [f"{v:+.3f}" for v in q]),
            _row("", ["+0.000", "+0.000"]),
            "",
            WORLD_AXES,
            _row("WORLD", ["+400.000", "+0.000", "+500.000", "+0.000", "+90.000", "+0.000"]),
            _row("", ["+0.000", "+0.000"]),
        ]

    def _armstat(self) -> list[str]:
        done = "N" if self.moving() else "Y"
        power = "Arm power is ON" if self.power else "Arm power is OFF"
        return [
            "",
            "Robot arm is of type A465",
            f"{power:<21}Robot is calibrated and homed",
            "Units are Metric     Online is OFF",
            "Physical stance: free free free",
            "",
            "Axis    locked   done   limped   homed",
            *[f"{a:>2}        N       {done}       N       Y" for a in range(1, 7)],
            "",
        ]

    def _answer(self, line: str) -> list[str]:
        words = line.split()
        name = words[0]
        if name in self.replace:
            return self.replace[name]
        if words == ["speed"]:
            return ["Current Speed: 50% of max."]
        if words in (["w0"], ["wcmd"]):
            return self._table("Commanded Position")
        if words in (["w2"], ["wact"]):
            return self._table("Actual Position")
        if words == ["armstat"]:
            return self._armstat()
        if name in ("joint", "ready", "home") and not self.power:
            return [f"{name}: Arm power is OFF"]
        if name == "joint" and len(words) == 3:
            target = self.joints() if not self.moving() else list(self._end)
            target[int(words[1]) - 1] += float(words[2])
            self._move_to(target)
            return []
        if words == ["ready"]:
            self._move_to(list(READY))
            return []
        if words == ["home"]:
            self._move_to([0.0] * 6)
            while self.moving():
                time.sleep(0.005)
            return [
                f"Seeking axis {a}...OK; Homing axis {a}...Ok, seek distance of 1520." for a in range(1, 7)
            ]
        return [f"shell: {name}: not found"]

    # ---------------------------------------------------------------- the line

    def _write(self, text: str) -> None:
        os.write(self.master, text.encode("latin-1"))

    def _serve(self) -> None:
        line = ""
        while True:
            ready, _, _ = select.select([self.master, self._stop_r], [], [])
            if self._stop_r in ready:
                return
            try:
                data = os.read(self.master, 1024)
            except OSError:
                return
            for byte in data:
                if byte == 0x1A:  # Ctrl-Z: the robot server halts the robot [F]
                    self.control_bytes.append(byte)
                    self._halt()
                    self._write("/sbin/robotsrv: ^Z detected - halting robot...\r\n")
                elif byte == 0x0D:
                    self._write("\r\n")
                    self._on_line(line)
                    line = ""
                elif byte == 0x0A:
                    continue
                else:  # printable or not, the byte joins the line (Ctrl-C is not special: SIGINT ignored)
                    if byte < 0x20:
                        self.control_bytes.append(byte)
                    line += chr(byte)
                    self._write(chr(byte) if byte >= 0x20 else "^" + chr(byte + 0x40))

    def _on_line(self, line: str) -> None:
        if not line.strip():
            self._write("$ ")
            return
        self.lines.append(line)
        name = line.split()[0]
        if name in self.drop:
            return
        reply = self._answer(line)
        if name in self.garble:
            reply = ["\x8f\x93#\xa1!\xfe"]
        self._write("".join(text + "\r\n" for text in reply) + "$ ")

    def close(self) -> None:
        os.write(self._stop_w, b"x")
        self._thread.join(timeout=5)
        for fd in (self.master, self.slave, self._stop_r, self._stop_w):
            os.close(fd)
