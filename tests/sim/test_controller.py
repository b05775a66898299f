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


def test_position_tables_and_errors_in_the_firmwares_format(twin_and_term):
    twin, term = twin_and_term
    term.type(b"w0\r")
    reply = term.until(b"$ ").decode()
    assert reply.startswith("w0\r\nCommanded Position :\r\n\r\n          Axis 1/7   Axis 2/8")
    assert "\r\nJOINTS      +0.000     +0.000    +90.000     +0.000    +90.000     +0.000\r\n" in reply
    assert "\r\nPULSES          +0         +0    +100000         +0     +50000         +0\r\n" in reply
    assert "\r\nWORLD     +330.000     +0.000   +559.000   -180.000     +0.000   +180.000\r\n" in reply
    assert "(mm)" not in reply  # no units row on the system shell
    term.type(b"joint 1 200\r")
    assert term.until(b"$ ") == b"joint 1 200\r\njoint: Joint 1 limit exceeded\r\n$ "
    term.type(b"joint 9 1\r")
    assert term.until(b"$ ") == b"joint 9 1\r\nInvalid axis '9'\r\nUsage: joint joint distance\r\n$ "
    term.type(b"speed 150\r")
    assert term.until(b"$ ").endswith(b"speed: invalid speed '150'\r\nUsage: speed [newspeed]\r\n$ ")
    term.type(b"fly\r")
    assert term.until(b"$ ") == b"fly\r\nshell: fly: not found\r\n$ "
    twin.set_power(False)
    term.type(b"ready\r")
    assert term.until(b"$ ").endswith(b"ready: Arm power is OFF\r\n$ ")
    term.type(b"armstat\r")
    assert b"\r\nArm power is OFF     Robot is calibrated and homed\r\n" in term.until(b"$ ")
    assert twin.received == ["w0", "joint 1 200", "joint 9 1", "speed 150", "fly", "ready", "armstat"]


def test_application_shell_prompt_commas_and_armstat():
    with start_twin(shell="application", app_name="cal", time_scale=100.0) as twin:
        term = Terminal(twin.port)
        try:
            term.type(b"joint 2,5\r")
            assert term.until(b"cal> ") == b"joint 2,5\r\ncal> "
            term.type(b"armstat\r")
            assert term.until(b"cal> ").decode().splitlines()[2:4] == [
                "Robot arm is of type A465",
                "Arm power is ON      Robot is calibrated and homed",
            ]
            term.type(b"speed\r")
            assert term.until(b"cal> ") == b"speed\r\nCurrent speed is 50\r\ncal> "
            term.type(b"nonsense\r")
            assert term.until(b"cal> ").endswith(b"error: Unrecognized command.\r\ncal> ")
        finally:
            term.close()
        for _ in range(100):
            if not twin.arm.moving():
                break
            time.sleep(0.01)
    assert twin.arm.commanded()[1] == 5.0


def test_by_default_the_prompt_comes_back_while_the_arm_moves_and_a_second_motion_is_held():
    with start_twin(speed_pct=20, time_scale=1.0) as twin:  # 20 deg at 36 deg/s: 0.6 s
        term = Terminal(twin.port)
        try:
            term.type(b"joint 1 20\r")
            assert term.until(b"$ ") == b"joint 1 20\r\n$ "
            assert twin.arm.moving()  # the prompt came back at once [F]
            term.type(b"joint 1 -20\r")
            assert term.until(b"joint 1 -20\r\n") == b"joint 1 -20\r\n"
            term.until(b"$ ")  # held until the first motion ended, then handed over
            assert twin.motion_log[0].end_deg[0] == 20.0
            assert not twin.motion_log[0].stopped
        finally:
            term.close()


def test_a_blocking_twin_prompts_when_the_motion_has_ended():
    with start_twin(motion_blocks=True, time_scale=100.0) as twin:
        term = Terminal(twin.port)
        try:
            term.type(b"joint 1 45\r")
            term.until(b"$ ")
            assert not twin.arm.moving()
            assert twin.motion_log[-1].end_deg[0] == 45.0
        finally:
            term.close()


def test_ctrl_c_is_ignored_by_a_motion_and_ctrl_z_halts_it():
    with start_twin(speed_pct=1, time_scale=1.0) as twin:  # 40 deg at 1.8 deg/s
        term = Terminal(twin.port)
        try:
            term.type(b"joint 1 40\r")
            term.until(b"$ ")
            term.type(b"\x03")
            assert term.until(b"^C") == b"^C"  # the byte stays in the line being typed [inferred]
            assert twin.arm.moving()
            term.type(b"\x1a")
            assert (
                term.until(b"halting robot...\r\n") == b"/sbin/robotsrv: ^Z detected - halting robot...\r\n"
            )
            assert not twin.arm.moving()
            assert twin.motion_log[-1].stopped
            assert 0.0 <= twin.arm.commanded()[0] < 40.0
            term.type(b"w2\r")  # merged with the ^C typed before: the shell does not know it
            assert term.until(b"$ ") == b"w2\r\nshell: \x03w2: not found\r\n$ "
        finally:
            term.close()


def test_ctrl_z_halts_a_blocking_motion_and_ctrl_c_can_be_made_to_stop():
    with start_twin(speed_pct=1, time_scale=1.0, motion_blocks=True, ctrl_c_stops=True) as twin:
        term = Terminal(twin.port)
        try:
            term.type(b"joint 2 30\r")
            assert term.until(b"joint 2 30\r\n") == b"joint 2 30\r\n"
            term.type(b"\x1a")
            assert term.until(b"$ ") == b"/sbin/robotsrv: ^Z detected - halting robot...\r\n$ "
            assert twin.motion_log[-1].stopped
            term.type(b"joint 2 30\r")
            term.until(b"joint 2 30\r\n")
            term.type(b"\x03")
            assert term.until(b"$ ") == b"^C\r\n$ "
            assert twin.motion_log[-1].stopped
        finally:
            term.close()


def test_home_waits_and_prints_each_axis_then_ready_and_calrdy():
    with start_twin(homed=False, time_scale=1000.0) as twin:
        term = Terminal(twin.port)
        try:
            term.type(b"ready\r")
            assert term.until(b"$ ").endswith(b"ready: Not homed or not calibrated\r\n$ ")
            term.type(b"home\r")
            lines = term.until(b"$ ").decode().splitlines()
            assert lines[1] == "Seeking axis 1...OK; Homing axis 1...Ok, seek distance of 1510."
            assert len(lines) == 8
            assert twin.arm.homed
            assert not twin.arm.moving()  # home waits [F]
            assert list(twin.arm.commanded()) == [0.0] * 6
            term.type(b"limp 3\r")
            term.until(b"$ ")
            term.type(b"ready\r")
            assert term.until(b"$ ").endswith(b"ready: Axis 3 is limp\r\n$ ")
            term.type(b"nolimp\r")
            term.until(b"$ ")
            term.type(b"calrdy\r")
            term.until(b"$ ")
            assert list(twin.arm.commanded()) == [0.0, 0.0, 90.0, 0.0, 90.0, 0.0]
            twin.set_power(False)
            term.type(b"home\r")
            assert term.until(b"$ ").endswith(b"Seeking axis 1...Failed.\r\nhome: Arm power is OFF\r\n$ ")
        finally:
            term.close()


def test_the_received_log_keeps_the_last_lines_only():
    with start_twin(log_limit=2) as twin:
        term = Terminal(twin.port)
        try:
            for command in (b"speed\r", b"w0\r", b"w2\r"):
                term.type(command)
                term.until(b"$ ")
        finally:
            term.close()
    assert twin.received == ["w0", "w2"]


# ------------------------------------------------------------------ faults on the wire


def test_fault_garble_sets_bit_7_and_keeps_the_prompt(twin_and_term):
    twin, term = twin_and_term
    twin.inject("garble@1")
    term.type(b"speed\r")
    out = term.until(b"$ ")
    assert out.startswith(b"speed\r\n")
    assert any(b >= 0x80 for b in out)
    term.type(b"speed 20\r")  # the next command is clean
    assert term.until(b"$ ") == b"speed 20\r\n$ "


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


def test_fault_on_a_command_skips_the_lines_before_it(twin_and_term):
    twin, term = twin_and_term
    twin.inject(Fault(kind=FaultKind.ERROR, on="joint 2", text="joint: 007 Arm power is OFF"))
    for line in (b"w0\r", b"joint 1 10\r", b"w0\r"):  # none of these is joint 2: all answered
        term.type(line)
        assert b"Arm power" not in term.until(b"$ ")
    term.type(b"joint 2 5\r")
    assert term.until(b"$ ") == b"joint 2 5\r\njoint: 007 Arm power is OFF\r\n$ "
    term.type(b"joint 2 5\r")  # fired once
    assert b"Arm power" not in term.until(b"$ ")


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


def test_fault_servo_stops_the_arm_and_the_robot_server_says_why():
    with start_twin(time_scale=1.0) as twin:  # 30 deg in about 0.46 s: the fault fires half-way
        term = Terminal(twin.port)
        try:
            twin.inject("servo@1:Collision error on axis 1")
            term.type(b"joint 1 30\r")
            out = term.until(b")\r\n")
            assert out.startswith(b"joint 1 30\r\n$ /sbin/robotsrv: Collision error on axis 1 (error code 0x")
            assert twin.motion_log[-1].stopped
        finally:
            term.close()


def test_fault_specs_parse():
    assert parse_fault("garble@3") == Fault(kind=FaultKind.GARBLE, at=3)
    assert parse_fault("servo@2:Runaway error on axis 4").text == "Runaway error on axis 4"
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
