"""A serial port that plays a C500C from a list of exact exchanges and fails on any surprise.

In the manner of PyMeasure's ``expected_protocol``: each :class:`Exchange` is the exact bytes the host
must write and the exact bytes the controller answers (echo, reply lines, prompt). The port fails
(``AssertionError``, also recorded in ``failures``) when the host writes anything unexpected, writes
before it has read the whole previous answer, or (``assert_done``) leaves exchanges unsent or
answers unread.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, TypedDict, Unpack

import serial

from drivers.crs_a465 import CrsA465, LinkSettings, MotionSettings, SafetyLimits, ShellProfile

PROMPT = "$ "


@dataclass(frozen=True)
class Exchange:
    sent: bytes
    reply: bytes


class ReplyOptions(TypedDict, total=False):
    """How ``say`` frames a reply: the prompt after it, and whether the command is echoed."""

    prompt: str
    echo: bool


def say(command: str, *reply: str, prompt: str = PROMPT, echo: bool = True) -> Exchange:
    """The host types ``command`` + CR; the controller echoes it, prints ``reply`` lines, then the prompt."""
    answer = (command + "\r\n" if echo else "") + "".join(line + "\r\n" for line in reply) + prompt
    return Exchange((command + "\r").encode("ascii"), answer.encode("latin-1"))


def silent(command: str) -> Exchange:
    """The host types ``command`` and the controller answers nothing at all (a dropped reply)."""
    return Exchange((command + "\r").encode("ascii"), b"")


def raw(sent: bytes, reply: bytes) -> Exchange:
    return Exchange(sent, reply)


class ScriptedPort(serial.SerialBase):
    """A ``serial.SerialBase`` driven by a script of :class:`Exchange`."""

    def __init__(self, exchanges: Iterable[Exchange]) -> None:
        self.script: list[Exchange] = list(exchanges)
        self.written = bytearray()
        self.failures: list[str] = []
        self._incoming = bytearray()
        self._outgoing = bytearray()
        super().__init__(port=None)
        self.is_open = True

    # the parts of SerialBase a port must provide
    def open(self) -> None:
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def _reconfigure_port(self) -> None:
        pass

    @property
    def in_waiting(self) -> int:
        return len(self._outgoing)

    def reset_input_buffer(self) -> None:
        self._fail(f"the host discarded input {bytes(self._outgoing)!r}")

    def reset_output_buffer(self) -> None:
        pass

    def flush(self) -> None:
        pass

    def _fail(self, message: str) -> None:
        self.failures.append(message)
        raise AssertionError(message)

    def read(self, size: int = 1) -> bytes:
        if not self._outgoing:
            time.sleep(self.timeout or 0.0)  # what a real port does when nothing comes
            return b""
        data = bytes(self._outgoing[:size])
        del self._outgoing[:size]
        return data

    def write(self, data: bytes) -> int:
        if self._outgoing:
            self._fail(f"the host wrote {bytes(data)!r} before reading {bytes(self._outgoing)!r}")
        self.written += data
        self._incoming += data
        while self._incoming:
            if not self.script:
                self._fail(f"the host wrote {bytes(self._incoming)!r} but nothing more was expected")
            expected = self.script[0].sent
            n = min(len(expected), len(self._incoming))
            if self._incoming[:n] != expected[:n]:
                self._fail(f"the host wrote {bytes(self._incoming)!r}, expected {expected!r}")
            if len(self._incoming) < len(expected):
                break
            del self._incoming[: len(expected)]
            self._outgoing += self.script.pop(0).reply
        return len(data)

    def assert_done(self) -> None:
        """Every exchange happened and every answer was read."""
        assert not self.failures, self.failures
        assert not self.script, f"exchanges never sent: {[e.sent for e in self.script]}"
        assert not self._incoming, f"incomplete command written: {bytes(self._incoming)!r}"
        assert not self._outgoing, f"answer never read: {bytes(self._outgoing)!r}"


@contextmanager
def scripted_robot(exchanges: Iterable[Exchange], **options: Any) -> Iterator[tuple[CrsA465, ScriptedPort]]:
    """``with scripted_robot([...]) as (robot, port):`` a driver on a scripted port.

    On a clean exit the block asserts that every scripted exchange happened and every answer was read:
    the verdict is in the test body, not in a fixture's teardown.
    """
    port = ScriptedPort(exchanges)
    options.setdefault("link", LinkSettings(reply_timeout_s=0.3, home_timeout_s=0.5, resync_quiet_s=0.02))
    options.setdefault("shell", ShellProfile.system())
    options.setdefault("safety", SafetyLimits())
    options.setdefault("motion", FAST_MOTION)
    robot = CrsA465(port, **options)
    yield robot, port
    port.assert_done()


# ------------------------------------------------------------------ reply texts of the dialect

AXES = "          Axis 1/7   Axis 2/8     Axis 3     Axis 4     Axis 5     Axis 6"
WORLD_AXES = "          X/TrackX   Y/TrackY          Z      Z-Rot      Y-Rot      X-Rot"
WORLD_UNITS = "WORLD         (mm)       (mm)       (mm)      (deg)      (deg)      (deg)"
COUNTS = (400000 / 360,) * 3 + (200000 / 360,) * 3
WORLD = (330.0, 0.0, 559.0, -180.0, 0.0, 180.0)


def _row(label: str, values: Iterable[str]) -> str:
    return f"{label:<8}" + " ".join(f"{v:>10}" for v in values)


def table(kind: str, joints: Iterable[float], world: Iterable[float] = WORLD) -> list[str]:
    """A ``w0``/``w2`` reply (``kind`` ``Commanded`` or ``Actual``) in the firmware's layout [F]."""
    q = list(joints)
    pulses = [round(v * c) for v, c in zip(q, COUNTS, strict=True)]
    return [
        f"{kind} Position :",
        "",
        AXES,
        _row("PULSES", (f"{p:+d}" for p in pulses)),
        _row("", ["+0", "+0"]),
        "",
        AXES,
        _row("JOINTS", (f"{v:+.3f}" for v in q)),
        _row("", ["+0.000", "+0.000"]),
        "",
        WORLD_AXES,
        _row("WORLD", (f"{v:+.3f}" for v in world)),
        _row("", ["+0.000", "+0.000"]),
    ]


def application_table(kind: str, joints: Iterable[float], world: Iterable[float] = WORLD) -> list[str]:
    """The application shell's layout [A: no public text of it; a units row, values below]."""
    q = list(joints)
    pulses = [round(v * c) for v, c in zip(q, COUNTS, strict=True)]
    return [
        f"{kind} Position :",
        AXES,
        "PULSES  " + "".join(f"{p:+11d}" for p in pulses),
        "        " + f"{0:+11d}" * 2,
        "JOINTS  " + "".join(f"{v:+11.3f}" for v in q),
        "        " + f"{0.0:+11.3f}" * 2,
        WORLD_AXES,
        WORLD_UNITS,
        "        " + "".join(f"{v:+11.3f}" for v in world),
    ]


READY = (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)


def w0(joints: Iterable[float] = READY, **kw: Unpack[ReplyOptions]) -> Exchange:
    return say("w0", *table("Commanded", joints), **kw)


def w2(joints: Iterable[float] = READY, **kw: Unpack[ReplyOptions]) -> Exchange:
    return say("w2", *table("Actual", joints), **kw)


def arrived(joints: Iterable[float], **kw: Unpack[ReplyOptions]) -> list[Exchange]:
    """The poll after a motion that finds the arm at ``joints``: w0 at the target, then armstat with
    every axis done and w2 there."""
    q = list(joints)
    return [w0(q, **kw), say("armstat", *armstat_lines(), **kw), w2(q, **kw)]


def still_polls(joints: Iterable[float], polls: int = 2, **kw: Unpack[ReplyOptions]) -> list[Exchange]:
    """``ready``/``home``'s polls that find the arm still at ``joints`` (w0 and w2 over ``polls`` polls)."""
    q = list(joints)
    return [e for _ in range(polls) for e in (w0(q, **kw), w2(q, **kw))]


def speed_report(percent: int = 50, **kw: Unpack[ReplyOptions]) -> Exchange:
    return say("speed", f"Current Speed: {percent}% of max.", **kw)


def armstat_lines(
    *, power: bool = True, homing: str = "Robot is calibrated and homed", moving: Iterable[int] = ()
) -> list[str]:
    """The firmware's armstat report [F]; ``moving`` axes show done N."""
    busy = set(moving)
    return [
        "",
        "Robot arm is of type A465",
        f"{'Arm power is ' + ('ON' if power else 'OFF'):<21}{homing}",
        "Units are Metric     Online is OFF",
        "Physical stance: free free free",
        "",
        "",
        "Current Tool Transform is: ",
        "tx=0.00000, ty=0.00000, tz=0.00000, yaw=0.00000, pitch=0.00000, roll=0.00000",
        "",
        "Current Base Transform is: ",
        "wx=0.00000, wy=0.00000, wz=0.00000, xrot=0.00000, yrot=0.00000, zrot=0.00000",
        "",
        "Axis    locked   done   limped   homed",
        *[f"{a:>2}        N       {'N' if a in busy else 'Y'}       N       Y" for a in range(1, 7)],
        "",
    ]


def armstat(**kw: Any) -> Exchange:
    prompt = kw.pop("prompt", PROMPT)
    return say("armstat", *armstat_lines(**kw), prompt=prompt)


def connect_exchanges(
    joints: Iterable[float] = READY, *, prompt: str = PROMPT, speed: int | None = None
) -> list[Exchange]:
    """What ``connect()`` says: an empty line, speed, armstat, w2, w0."""
    q = list(joints)
    return [
        say("", prompt=prompt),
        speed_report(prompt=prompt) if speed is None else speed_report(speed, prompt=prompt),
        armstat(prompt=prompt),
        w2(q, prompt=prompt),
        w0(q, prompt=prompt),
    ]


FAST_MOTION = MotionSettings(deadline_margin_s=1.0, stall_timeout_s=0.5, poll_interval_s=0.0, reuse_s=60.0)
"""Scripted ports answer at once: no pause between polls, short deadlines; the readings of an arrival
stand for the next move's start and where() until something is sent (never by age within a test)."""
