"""The controller twin seen from a raw terminal (no driver): echo, prompt, replies, timing, faults."""

from __future__ import annotations

import os
import select
import time
import tty
from collections.abc import Iterator

import pytest

from sim.controller import ControllerTwin, Fault, FaultKind, TwinSettings, parse_fault, start_twin


class Terminal:
    """The slave side of the twin's pty, opened raw, as any program would."""

    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)

    def type(self, data: bytes) -> None:
        os.write(self.fd, data)

    def until(self, end: bytes, timeout_s: float = 5.0) -> bytes:
        """Read until the output ends with ``end``; fail after ``timeout_s`` (a hang, not a timing check)."""
        got = b""
        deadline = time.monotonic() + timeout_s
        while not got.endswith(end):
            remaining = deadline - time.monotonic()
            assert remaining > 0, f"no {end!r} after {got!r}"
            ready, _, _ = select.select([self.fd], [], [], remaining)
            if ready:
                try:
                    chunk = os.read(self.fd, 4096)
                except OSError:  # EIO: the other side hung up
                    chunk = b""
                if not chunk:
                    return got + b"<HUP>"
                got += chunk
        return got

    def nothing_for(self, seconds: float) -> bool:
        ready, _, _ = select.select([self.fd], [], [], seconds)
        return not ready

    def close(self) -> None:
        os.close(self.fd)


@pytest.fixture
def twin_and_term() -> Iterator[tuple[ControllerTwin, Terminal]]:
    twin = start_twin(time_scale=100.0, seed=1)
    term = Terminal(twin.port)
    yield twin, term
    term.close()
    twin.close()


def test_echoes_and_prompts(twin_and_term):
    _, term = twin_and_term
    term.type(b"\r")
    assert term.until(b"$ ") == b"\r\n$ "
    term.type(b"speed\r")
    assert term.until(b"$ ") == b"speed\r\nCurrent Speed: 50% of max.\r\n$ "


def test_accepts_cr_lf_and_backspace(twin_and_term):
    _, term = twin_and_term
    term.type(b"spex\x7fed\r\n")
    assert term.until(b"$ ").endswith(b"Current Speed: 50% of max.\r\n$ ")
    assert term.nothing_for(0.05)  # the LF after CR is not a second command


def test_position_tables_and_errors_in_the_docs_format(twin_and_term):
    twin, term = twin_and_term
    term.type(b"w0\r")
    reply = term.until(b"$ ").decode()
    assert "Commanded Position :\r\n" in reply
    assert "JOINTS       +0.000     +0.000    +90.000     +0.000    +90.000     +0.000\r\n" in reply
    assert "PULSES           +0         +0    +100000         +0     +50000         +0\r\n" in reply
    term.type(b"joint 1 200\r")
    assert term.until(b"$ ") == b"joint 1 200\r\njoint: 001 Joint 1 limit exceeded\r\n$ "
    term.type(b"speed 0\r")
    assert term.until(b"$ ").endswith(b"speed: 015 Illegal speed chosen\r\n$ ")
    term.type(b"fly\r")
    assert term.until(b"$ ") == b"fly\r\nUnrecognized command.\r\n$ "
    twin.set_power(False)
    term.type(b"ready\r")
    assert term.until(b"$ ").endswith(b"ready: 007 Arm power is OFF\r\n$ ")
    assert twin.received == ["w0", "joint 1 200", "speed 0", "fly", "ready"]


def test_application_shell_prompt_commas_and_armstat():
    with start_twin(shell="application", app_name="cal", time_scale=100.0) as twin:
        term = Terminal(twin.port)
        try:
            term.type(b"joint 2,5\r")
            assert term.until(b"cal> ") == b"joint 2,5\r\ncal> "
            term.type(b"armstat\r")
            assert term.until(b"cal> ").decode().splitlines()[1:3] == [
                "Robot arm is of type A465",
                "Arm Power is ON",
            ]
            term.type(b"nonsense\r")
            assert term.until(b"cal> ").endswith(b"error: Unrecognized command.\r\ncal> ")
        finally:
            term.close()
    assert twin.arm.commanded()[1] == 5.0


def test_a_blocking_motion_prompts_when_it_has_ended(twin_and_term):
    twin, term = twin_and_term
    term.type(b"joint 1 45\r")
    term.until(b"$ ")
    assert not twin.arm.moving()
    assert twin.motion_log[-1].end_deg[0] == 45.0


def test_a_non_blocking_motion_prompts_at_once_and_ctrl_c_stops_it():
    with start_twin(motion_blocks=False, speed_pct=1, time_scale=1.0) as twin:  # 40 deg at 1.8 deg/s
        term = Terminal(twin.port)
        try:
            term.type(b"joint 1 40\r")
            term.until(b"$ ")
            assert twin.arm.moving()
            term.type(b"\x03")
            assert term.until(b"$ ") == b"^C\r\n$ "
            assert not twin.arm.moving()
            assert twin.motion_log[-1].stopped
            assert 0.0 <= twin.arm.commanded()[0] < 40.0
        finally:
            term.close()


def test_ctrl_c_stops_a_blocking_motion():
    with start_twin(speed_pct=1, time_scale=1.0) as twin:
        term = Terminal(twin.port)
        try:
            term.type(b"joint 2 30\r")
            assert term.until(b"joint 2 30\r\n") == b"joint 2 30\r\n"
            term.type(b"\x03")
            assert term.until(b"$ ") == b"^C\r\n$ "
            assert twin.motion_log[-1].stopped
        finally:
            term.close()


def test_home_then_ready_and_calrdy():
    with start_twin(homed=False, time_scale=1000.0) as twin:
        term = Terminal(twin.port)
        try:
            term.type(b"ready\r")
            assert term.until(b"$ ").endswith(b"ready: 005 Not homed or not calibrated\r\n$ ")
            term.type(b"home\r")
            term.until(b"$ ")
            assert twin.arm.homed
            assert list(twin.arm.commanded()) == [0.0] * 6
            term.type(b"limp 3\r")
            term.until(b"$ ")
            term.type(b"ready\r")
            assert term.until(b"$ ").endswith(b"ready: 004 Axis 3 is limp\r\n$ ")
            term.type(b"nolimp\r")
            term.until(b"$ ")
            term.type(b"calrdy\r")
            term.until(b"$ ")
            assert list(twin.arm.commanded()) == [0.0, 0.0, 90.0, 0.0, 90.0, 0.0]
        finally:
            term.close()


# ------------------------------------------------------------------ faults on the wire


def test_fault_garble_sets_bit_7_and_keeps_the_prompt(twin_and_term):
    twin, term = twin_and_term
    twin.inject("garble@1")
    term.type(b"speed\r")
    out = term.until(b"$ ")
    assert out.startswith(b"speed\r\n")
    assert any(b >= 0x80 for b in out)
    term.type(b"joint 1 1\r")  # the next command is clean
    assert term.until(b"$ ") == b"joint 1 1\r\n$ "


def test_fault_drop_echoes_then_says_nothing(twin_and_term):
    twin, term = twin_and_term
    twin.inject(Fault(kind=FaultKind.DROP))
    term.type(b"w2\r")
    assert term.until(b"w2\r\n") == b"w2\r\n"
    assert term.nothing_for(0.1)
    term.type(b"\r")
    assert term.until(b"$ ") == b"\r\n$ "


def test_fault_error_replaces_the_command(twin_and_term):
    twin, term = twin_and_term
    twin.inject(
        "error@2:Process 193: exception raised (code = 'Arm power is OFF')\\n  in module './x' at x.r3:65"
    )
    term.type(b"speed\r")
    term.until(b"$ ")
    term.type(b"joint 1 10\r")
    assert term.until(b"$ ") == (
        b"joint 1 10\r\nProcess 193: exception raised (code = 'Arm power is OFF')\r\n"
        b"  in module './x' at x.r3:65\r\n$ "
    )
    assert twin.motion_log == []


def test_fault_slow_delays_the_reply(twin_and_term):
    twin, term = twin_and_term
    twin.inject(Fault(kind=FaultKind.SLOW, delay_s=0.2))
    term.type(b"speed\r")
    assert term.until(b"speed\r\n") == b"speed\r\n"
    assert term.nothing_for(0.05)
    assert term.until(b"$ ") == b"Current Speed: 50% of max.\r\n$ "


def test_fault_disconnect_removes_the_pty_and_replug_brings_a_new_one():
    with start_twin(link="auto", time_scale=100.0) as twin:
        link = twin.port
        term = Terminal(link)
        try:
            twin.inject("disconnect@1")
            term.type(b"speed\r")
            assert term.until(b"<HUP>").endswith(b"<HUP>")
        finally:
            term.close()
        assert not os.path.exists(link)
        twin.replug()
        assert os.path.realpath(link) == twin.pty_path
        assert twin.pty_path is not None
        term = Terminal(link)
        try:
            term.type(b"\r")
            assert term.until(b"$ ") == b"\r\n$ "
        finally:
            term.close()


def test_unplug_from_outside(twin_and_term):
    twin, term = twin_and_term
    twin.unplug()
    assert term.until(b"<HUP>").endswith(b"<HUP>")


# ------------------------------------------------------------------ settings


def test_fault_specs_parse():
    assert parse_fault("garble@3") == Fault(kind=FaultKind.GARBLE, at=3)
    assert parse_fault("slow:1.5") == Fault(kind=FaultKind.SLOW, delay_s=1.5)
    assert parse_fault("disconnect@2:0.5").replug_after_s == 0.5
    assert parse_fault("error@1:001 Joint 2 limit exceeded").text == "001 Joint 2 limit exceeded"
    for bad in ("melt@1", "drop@x", "garble@1:3"):
        with pytest.raises(ValueError, match="fault"):
            parse_fault(bad)


def test_settings_take_one_number_for_all_joints_and_refuse_unknown_keys():
    assert TwinSettings(repeat_sigma_deg=0.01).repeat_sigma_deg == (0.01,) * 6
    assert TwinSettings(faults=["drop@2"]).faults == (Fault(kind=FaultKind.DROP, at=2),)
    with pytest.raises(ValueError, match="extra"):
        TwinSettings(colour="red")  # type: ignore[call-arg]
    with pytest.raises(ValueError, match="greater than 0"):
        TwinSettings(time_scale=0)


def test_close_is_idempotent_and_joins_the_thread():
    twin = start_twin()
    twin.close()
    twin.close()
    assert twin._thread is not None
    assert not twin._thread.is_alive()
