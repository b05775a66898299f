"""The driver against recorded exchanges: the exact lines sent and received for each command.

The scripted port fails on any unexpected, missing or unread line (fakes.ScriptedPort).
"""

from __future__ import annotations

import pytest

from drivers.crs_a465 import (
    ArmPowerOffError,
    JointLimitError,
    NotHomedError,
    RaplExceptionError,
    ShellProfile,
    UnknownCommandError,
)
from station.devices import (
    DeviceProtocolError,
    DeviceTimeoutError,
    MotionRejectedError,
    MotionStoppedError,
    RobotStatus,
)
from tests.drivers.crs_a465.fakes import (
    READY,
    ScriptedPort,
    connect_exchanges,
    raw,
    say,
    silent,
    speed_report,
    table,
    w0,
    w2,
)


def test_fake_port_fails_on_an_unexpected_line():
    port = ScriptedPort([say("w0")])
    with pytest.raises(AssertionError, match="expected"):
        port.write(b"w2\r")


def test_fake_port_fails_on_a_line_written_before_the_answer_was_read():
    port = ScriptedPort([say("w0", "x"), say("w2")])
    port.write(b"w0\r")
    with pytest.raises(AssertionError, match="before reading"):
        port.write(b"w2\r")


def test_fake_port_fails_on_a_missing_exchange_or_an_unread_answer():
    port = ScriptedPort([say("w0"), say("w2")])
    port.write(b"w0\r")
    with pytest.raises(AssertionError):
        port.assert_done()


def test_connect_finds_the_prompt_then_reads_speed_and_positions(scripted):
    robot, _ = scripted(connect_exchanges())
    robot.connect()
    assert robot.last_status == RobotStatus(power=None, homed=None, moving=None, speed_pct=50.0)
    assert robot.last_position is not None
    assert robot.last_position.commanded_joints_deg == READY


def test_where_reads_w2_then_w0(scripted):
    actual = (0.001, -0.002, 90.0, 0.0, 89.999, 0.0)
    robot, _ = scripted([*connect_exchanges(), w2(actual), w0(READY)])
    robot.connect()
    p = robot.where()
    assert p.joints_deg == actual
    assert p.commanded_joints_deg == READY
    assert p.world_mm_deg == (330.0, 0.0, 559.0, -180.0, 0.0, 180.0)


def test_status_on_the_system_shell_reports_power_and_homing_as_unknown(scripted):
    robot, _ = scripted([*connect_exchanges(), speed_report(35)])
    robot.connect()
    assert robot.status() == RobotStatus(power=None, homed=None, moving=None, speed_pct=35.0)


def test_status_on_the_application_shell_reads_armstat(scripted):
    p = "ash> "
    robot, _ = scripted(
        [
            *connect_exchanges(prompt=p)[:2],
            say(
                "armstat",
                "Robot arm is of type A465",
                "Arm Power is OFF",
                "Robot is calibrated and homed",
                prompt=p,
            ),
            *connect_exchanges(prompt=p)[2:],
            speed_report(50, prompt=p),
            say("armstat", "Arm Power is ON", "Robot is not homed", prompt=p),
        ],
        shell=ShellProfile.application("ash"),
    )
    robot.connect()
    assert robot.last_status == RobotStatus(power=False, homed=True, moving=None, speed_pct=50.0)
    assert robot.status() == RobotStatus(power=True, homed=False, moving=None, speed_pct=50.0)


def test_move_joint_reads_w0_then_sends_one_relative_move(scripted):
    robot, _ = scripted([*connect_exchanges(), w0(), say("joint 2 -5.250")])
    robot.connect()
    robot.move_joint(2, -5.25)


def test_application_shell_separates_arguments_with_commas(scripted):
    p = "cal> "
    robot, _ = scripted(
        [
            say("", prompt=p),
            speed_report(prompt=p),
            say("armstat", "Arm Power is ON", "Robot is calibrated and homed", prompt=p),
            w2(prompt=p),
            w0(prompt=p),
            w0(prompt=p),
            say("joint 4,12.500", prompt=p),
        ],
        shell=ShellProfile.application("cal"),
    )
    robot.connect()
    robot.move_joint(4, 12.5)


def test_move_joints_composes_relative_moves_from_w0_and_verifies(scripted):
    start = (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    target = (10.0, 5.0, 80.0, 0.0, 85.0, 3.0)
    robot, _ = scripted(
        [
            *connect_exchanges(),
            w0(start),
            say("joint 1 10.000"),
            say("joint 2 5.000"),
            say("joint 3 -10.000"),
            say("joint 5 -5.000"),
            say("joint 6 3.000"),
            w0(target),
        ]
    )
    robot.connect()
    robot.move_joints(target)


def test_move_joints_rounds_to_the_controllers_resolution(scripted):
    robot, _ = scripted([*connect_exchanges(), w0(), say("joint 1 1.235"), w0((1.235, 0, 90, 0, 90, 0))])
    robot.connect()
    robot.move_joints((1.2346, 0, 90, 0, 90, 0))


def test_move_joints_fails_when_the_controller_commands_another_position(scripted):
    robot, _ = scripted([*connect_exchanges(), w0(), say("joint 1 10.000"), w0(READY)])
    robot.connect()
    with pytest.raises(DeviceProtocolError, match="joint 1"):
        robot.move_joints((10, 0, 90, 0, 90, 0))


def test_set_speed_sends_the_percent_and_reads_it_back(scripted):
    robot, _ = scripted([*connect_exchanges(), say("speed 80"), speed_report(80)])
    robot.connect()
    robot.set_speed(80)


@pytest.mark.parametrize("bad", [0, 101, 12.5, float("nan")])
def test_set_speed_rejects_a_bad_percent_before_writing(scripted, bad):
    robot, _ = scripted(connect_exchanges())
    robot.connect()
    with pytest.raises(ValueError, match="speed"):
        robot.set_speed(bad)


def test_home_and_ready(scripted):
    robot, _ = scripted([*connect_exchanges(), say("home"), w0((0,) * 6), say("ready")])
    robot.connect()
    robot.home()
    robot.ready()


@pytest.mark.parametrize(
    ("reply", "error", "code", "axis"),
    [
        (["joint: 007 Arm power is OFF"], ArmPowerOffError, 7, None),
        (["joint: 001 Joint 2 limit exceeded"], JointLimitError, 1, 2),
        (["joint: 005 Not homed or not calibrated"], NotHomedError, 5, None),
        (
            [
                "Process 193: exception raised (code = 'Arm power is OFF')",
                "  in module './joint' at joint.r3:65",
            ],
            ArmPowerOffError,
            None,
            None,
        ),
        (
            ["Process 12: exception raised (code = 'Something odd')", "  in module './x' at x.r3:1"],
            RaplExceptionError,
            None,
            None,
        ),
        (["Unrecognized command."], UnknownCommandError, None, None),
    ],
)
def test_controller_errors_become_typed_exceptions(scripted, reply, error, code, axis):
    robot, _ = scripted([*connect_exchanges(), w0(), say("joint 2 1.000", *reply), speed_report()])
    robot.connect()
    with pytest.raises(error) as info:
        robot.move_joint(2, 1.0)
    assert info.value.code == code
    assert info.value.axis == axis
    assert reply[0].strip() in info.value.controller_text
    assert robot.status().last_error == info.value.controller_text


def test_a_query_that_gets_no_prompt_times_out_then_the_link_resyncs(scripted):
    robot, _ = scripted([*connect_exchanges(), silent("w2"), say(""), w2(), w0()])
    robot.connect()
    with pytest.raises(DeviceTimeoutError, match="no prompt"):
        robot.where()
    assert robot.where().commanded_joints_deg == READY


def test_a_late_reply_is_skipped_by_the_resync(scripted):
    late = ("w0\r\n" + "\r\n".join(table("Commanded", READY)) + "\r\n$ ").encode()
    robot, _ = scripted(
        [*connect_exchanges(), silent("w0"), raw(b"\r", late + b"\r\n$ "), w0(), say("joint 1 1.000")]
    )
    robot.connect()
    with pytest.raises(DeviceTimeoutError):
        robot.move_joint(1, 1.0)
    robot.move_joint(1, 1.0)


def test_a_wrong_echo_is_a_protocol_error(scripted):
    robot, _ = scripted([*connect_exchanges(), raw(b"w2\r", b"w3\r\n$ ")])
    robot.connect()
    with pytest.raises(DeviceProtocolError, match="echo"):
        robot.where()


def test_output_before_the_echo_is_logged_and_its_error_remembered(scripted, caplog):
    robot, _ = scripted(
        [
            *connect_exchanges(),
            raw(b"speed\r", b"004 Collision error on axis 3\r\nspeed\r\nCurrent Speed: 50% of max.\r\n$ "),
        ]
    )
    robot.connect()
    assert robot.status().last_error == "004 Collision error on axis 3"
    assert "unasked" in caplog.text


def test_stop_while_idle_sends_ctrl_c_and_the_next_command_resyncs(scripted):
    robot, _ = scripted([*connect_exchanges(), raw(b"\x03", b"^C\r\n$ "), say(""), speed_report()])
    robot.connect()
    robot.stop()
    assert robot.status().speed_pct == 50.0


def test_a_motion_answered_with_ctrl_c_raises_motion_stopped(scripted):
    stopped = (7.5, 0.0, 90.0, 0.0, 90.0, 0.0)
    robot, _ = scripted(
        [*connect_exchanges(), w0(), say("joint 1 20.000", "^C"), say(""), w2(stopped), w0(stopped)]
    )
    robot.connect()
    with pytest.raises(MotionStoppedError):
        robot.move_joint(1, 20)
    assert robot.where().commanded_joints_deg == stopped


def test_noise_after_a_motion_is_a_protocol_error(scripted):
    robot, _ = scripted([*connect_exchanges(), w0(), say("joint 1 1.000", "\x8f\x93#\xa1")])
    robot.connect()
    with pytest.raises(DeviceProtocolError, match="non-printable"):
        robot.move_joint(1, 1.0)


def test_rejected_motion_writes_nothing(scripted):
    robot, port = scripted(connect_exchanges())
    robot.connect()
    before = bytes(port.written)
    with pytest.raises(MotionRejectedError, match="nothing was sent"):
        robot.move_joints((0, 0, 90, 0, 120, 0))
    assert bytes(port.written) == before
