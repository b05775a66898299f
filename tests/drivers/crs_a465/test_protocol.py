"""The driver against recorded exchanges: the exact lines sent and received for each command.

Each test runs inside ``scripted_robot``: the scripted port fails on any unexpected line, and the
``with`` block's exit asserts that every exchange happened and every answer was read.
"""

from __future__ import annotations

import logging

import pytest

from drivers.crs_a465 import (
    ArmPowerOffError,
    ArrivalError,
    ControllerUsageError,
    JointLimitError,
    MotionSettings,
    NotHomedError,
    RaplExceptionError,
    SafetyLimits,
    ServoError,
    ShellProfile,
    UnexpectedReplyError,
    UnknownCommandError,
)
from station.devices import (
    DeviceError,
    DeviceIdentity,
    DeviceProtocolError,
    DeviceTimeoutError,
    MotionRejectedError,
    MotionStoppedError,
    RobotStatus,
)
from station.speed_cap import SpeedCapError
from tests.drivers.crs_a465.fakes import (
    FAST_MOTION,
    READY,
    ScriptedPort,
    application_table,
    armstat,
    arrived,
    connect_exchanges,
    raw,
    say,
    scripted_robot,
    silent,
    speed_report,
    still_polls,
    table,
    w0,
    w2,
)
from tests.local_ack import local_ack

HALT = "/sbin/robotsrv: ^Z detected - halting robot..."


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


def test_the_scripted_block_fails_when_an_exchange_never_happened():
    with (
        pytest.raises(AssertionError, match="never sent"),
        scripted_robot([*connect_exchanges(), w0()]) as (robot, _),
    ):
        robot.connect()


def test_connect_finds_the_prompt_then_reads_speed_armstat_and_positions():
    with scripted_robot(connect_exchanges()) as (robot, _):
        robot.connect()
    assert robot.last_status == RobotStatus(
        power=True, homed=True, moving=False, speed_pct=50.0, calibrated=True, arm_type="A465"
    )
    assert robot.last_position is not None
    assert robot.last_position.commanded_joints_deg == READY
    assert robot.identity() == DeviceIdentity(model="A465", serial=None, port="ScriptedPort", firmware=None)


def test_where_reads_w2_then_w0():
    actual = (0.001, -0.002, 90.0, 0.0, 89.999, 0.0)
    with scripted_robot([*connect_exchanges(), w2(actual), w0(READY)]) as (robot, _):
        robot.connect()
        p = robot.where()
    assert p.joints_deg == actual
    assert p.commanded_joints_deg == READY
    assert p.world_mm_deg == (330.0, 0.0, 559.0, -180.0, 0.0, 180.0)


def test_status_reports_power_off_and_motion_from_armstat():
    with scripted_robot(
        [
            *connect_exchanges(),
            speed_report(35),
            armstat(power=False, homing="Robot is calibrated", moving=[2]),
        ]
    ) as (robot, _):
        robot.connect()
        status = robot.status()
    assert status == RobotStatus(
        power=False, homed=False, moving=True, speed_pct=35.0, calibrated=True, arm_type="A465"
    )


def test_status_on_the_application_shell_reads_armstat_and_its_speed_form():
    p = "ash> "
    with scripted_robot(
        [
            say("", prompt=p),
            say("speed", "Current speed is 40", prompt=p),
            armstat(prompt=p, homing="Robot is not homed"),
            say("w2", *application_table("Actual", READY), prompt=p),
            say("w0", *application_table("Commanded", READY), prompt=p),
        ],
        shell=ShellProfile.application("ash"),
    ) as (robot, _):
        robot.connect()
    assert robot.last_status is not None
    assert (robot.last_status.speed_pct, robot.last_status.homed) == (40.0, False)


def test_move_joint_sends_one_relative_move_then_waits_for_arrival():
    # while the arm moves only w0 is polled; once it is at the target, armstat (every axis done) and w2
    target = (0.0, -5.25, 90.0, 0.0, 90.0, 0.0)
    moving = (0.0, -2.0, 90.0, 0.0, 90.0, 0.0)
    with scripted_robot(
        [*connect_exchanges(), w0(), say("joint 2 -5.250"), w0(moving), w0(moving), *arrived(target)]
    ) as (robot, _):
        robot.connect()
        robot.move_joint(2, -5.25)
    assert robot.last_arrival is not None
    assert robot.last_arrival.error_deg == pytest.approx((0.0,) * 6, abs=1e-9)


def test_arrival_reports_the_servo_error_and_fails_only_when_gross():
    # a still arm grossly away from the target is not taken as arrived: the stall timeout decides
    target = (1.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    close = (1.02, 0.0, 90.0, 0.0, 90.0, 0.0)
    with scripted_robot(
        [
            *connect_exchanges(),
            w0(),
            say("joint 1 1.000"),
            w0(target),
            armstat(),
            w2(close),
            # the next move starts from the arrival's w0 (nothing sent since): no w0 before it
            say("joint 1 -1.000"),
            w0(READY),
            armstat(),
            w2((0.8, 0, 90, 0, 90, 0)),
            armstat(),
            w2((0.8, 0, 90, 0, 90, 0)),
        ],
        motion=MotionSettings(stall_timeout_s=1e-6, deadline_margin_s=1.0, poll_interval_s=0.0, reuse_s=60.0),
    ) as (robot, _):
        robot.connect()
        robot.move_joint(1, 1.0)
        assert robot.last_arrival is not None
        assert robot.last_arrival.error_deg is not None
        assert robot.last_arrival.error_deg[0] == pytest.approx(0.02)
        with pytest.raises(ArrivalError, match=r"joint 1 at 0\.800 deg, \+0\.800 deg from the target"):
            robot.move_joint(1, -1.0)


def test_a_still_arm_far_from_a_commanded_target_has_not_arrived_yet():
    # should w0 show the final target at once, an arm that has not started yet is not "arrived"
    target = (0.0, 0.0, 90.0, 0.0, 90.0, 10.0)
    mid = (0.0, 0.0, 90.0, 0.0, 90.0, 4.0)
    with scripted_robot(
        [
            *connect_exchanges(),
            w0(),
            say("joint 6 10.000"),
            w0(target),
            *[e for q in (READY, READY, mid, target) for e in (armstat(), w2(q))],
        ]
    ) as (robot, _):
        robot.connect()
        robot.move_joint(6, 10.0)
    assert robot.last_arrival is not None
    assert robot.last_arrival.actual_deg == target


def test_application_shell_separates_arguments_with_commas():
    p = "cal> "
    target = (0.0, 0.0, 90.0, 12.5, 90.0, 0.0)
    with scripted_robot(
        [
            say("", prompt=p),
            speed_report(prompt=p),
            armstat(prompt=p),
            w2(prompt=p),
            w0(prompt=p),
            w0(prompt=p),
            say("joint 4,12.500", prompt=p),
            *arrived(target, prompt=p),
        ],
        shell=ShellProfile.application("cal"),
    ) as (robot, _):
        robot.connect()
        robot.move_joint(4, 12.5)


def test_move_joints_composes_relative_moves_from_w0_and_waits_after_each():
    start = (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    steps = [
        ("joint 1 10.000", (10.0, 0.0, 90.0, 0.0, 90.0, 0.0)),
        ("joint 2 5.000", (10.0, 5.0, 90.0, 0.0, 90.0, 0.0)),
        ("joint 3 -10.000", (10.0, 5.0, 80.0, 0.0, 90.0, 0.0)),
        ("joint 5 -5.000", (10.0, 5.0, 80.0, 0.0, 85.0, 0.0)),
        ("joint 6 3.000", (10.0, 5.0, 80.0, 0.0, 85.0, 3.0)),
    ]
    script = [*connect_exchanges(), w0(start)]
    for line, reached in steps:
        script += [say(line), *arrived(reached)]
    with scripted_robot(script) as (robot, _):
        robot.connect()
        robot.move_joints(steps[-1][1])


def test_move_joints_rounds_to_the_controllers_resolution():
    target = (1.235, 0, 90, 0, 90, 0)
    with scripted_robot([*connect_exchanges(), w0(), say("joint 1 1.235"), *arrived(target)]) as (robot, _):
        robot.connect()
        robot.move_joints((1.2346, 0, 90, 0, 90, 0))


def test_move_joints_fails_when_the_arm_stops_short_of_the_target():
    # w0 and w2 never reach the target and stop changing: a stall, not success
    with scripted_robot(
        [*connect_exchanges(), w0(), say("joint 1 10.000"), w0(READY), w0(READY)],
        motion=MotionSettings(stall_timeout_s=1e-6, deadline_margin_s=1.0, poll_interval_s=0.0),
    ) as (robot, _):
        robot.connect()
        with pytest.raises(ArrivalError, match=r"stopped short: joint 1 is commanded at 0\.000 deg"):
            robot.move_joints((10, 0, 90, 0, 90, 0))


def test_set_speed_sends_the_percent_and_reads_it_back():
    with scripted_robot(
        [*connect_exchanges(), say("speed 80"), speed_report(80)], safety=SafetyLimits(max_speed_pct=80)
    ) as (robot, _):
        robot.connect()
        robot.set_speed(80)


def test_a_speed_above_the_cap_is_refused_before_writing_and_says_where_the_cap_is_set():
    with scripted_robot(connect_exchanges()) as (robot, port):  # the default cap: 50 %
        robot.connect()
        written = bytes(port.written)
        with pytest.raises(
            SpeedCapError, match=r"80 % refused: the station's speed cap is 50 % \(max_speed_pct"
        ):
            robot.set_speed(80)
        with pytest.raises(SpeedCapError):
            robot.check_speed(51)
        robot.check_speed(50)
        assert bytes(port.written) == written


def test_no_motion_at_a_controller_speed_above_the_cap():
    """The pendant left the override at 80 %: every motion is refused until it is set within the cap."""
    with scripted_robot([*connect_exchanges(speed=80), w0()]) as (robot, port):
        robot.connect()
        with pytest.raises(SpeedCapError, match="speed override is 80 %, above the station's cap of 50 %"):
            robot.move_joint(1, 1.0)
        assert not port.written.endswith(b"joint 1 1.000\r")


@pytest.mark.parametrize("bad", [0, 101, 12.5, float("nan")])
def test_set_speed_rejects_a_bad_percent_before_writing(bad):
    with scripted_robot(connect_exchanges()) as (robot, _):
        robot.connect()
        with pytest.raises(ValueError, match="speed"):
            robot.set_speed(bad)


HOME_LINES = [f"Seeking axis {a}...OK; Homing axis {a}...Ok, seek distance of 1520." for a in range(1, 7)]


def test_home_and_ready_wait_for_arrival_and_armstat_done():
    home = (0.0,) * 6
    with scripted_robot(
        [
            *connect_exchanges(),
            w0(),  # home's path is checked from where the arm is
            say("home", *HOME_LINES),
            *still_polls(home),
            armstat(),
            w0(home),
            say("ready"),
            *still_polls(READY),
            armstat(moving=[3]),  # still and at rest per w0/w2, but armstat says axis 3 is not done
            *still_polls(READY, polls=1),
            armstat(),
        ]
    ) as (robot, _):
        robot.connect()
        robot.home()
        robot.ready()


def test_ready_ending_elsewhere_than_the_configured_pose_warns(caplog):
    elsewhere = (0.0, 0.0, 90.0, 0.0, 0.0, 0.0)
    with scripted_robot([*connect_exchanges(), w0(), say("ready"), *still_polls(elsewhere), armstat()]) as (
        robot,
        _,
    ):
        robot.connect()
        with caplog.at_level(logging.WARNING):
            robot.ready()
    assert "not the configured pose" in caplog.text


@pytest.mark.parametrize(
    ("reply", "error", "axis"),
    [
        (["joint: Arm power is OFF"], ArmPowerOffError, None),
        (["joint: Joint 2 limit exceeded"], JointLimitError, 2),
        (["joint: Not homed or not calibrated"], NotHomedError, None),
        (["Invalid axis '2'", "Usage: joint joint distance"], ControllerUsageError, None),
        (
            [
                "Process 193: exception raised (code = 'Arm power is OFF')",
                "  in module './joint' at joint.r3:65",
            ],
            ArmPowerOffError,
            None,
        ),
        (
            ["Process 12: exception raised (code = 'Something odd')", "  in module './x' at x.r3:1"],
            RaplExceptionError,
            None,
        ),
        (["shell: joint: not found"], UnknownCommandError, None),
        (["Joint 1 limit"], UnexpectedReplyError, None),  # unknown text after a motion is never success
    ],
)
def test_controller_errors_become_typed_exceptions(reply, error, axis):
    with scripted_robot(
        [*connect_exchanges(), w0(), say("joint 2 1.000", *reply), speed_report(), armstat()]
    ) as (robot, _):
        robot.connect()
        with pytest.raises(error) as info:
            robot.move_joint(2, 1.0)
        assert info.value.axis == axis
        assert reply[0].strip() in info.value.controller_text
        assert robot.status().last_error == info.value.controller_text


def test_a_robot_server_error_during_the_motion_is_the_motions_error():
    moving = (0.5, 0.0, 90.0, 0.0, 90.0, 0.0)
    server = "/sbin/robotsrv: Excessive lag error on axis 1 (error code 0x7021)"
    with scripted_robot(
        [
            *connect_exchanges(),
            w0(),
            say("joint 1 2.000"),
            w0(moving),
            raw(
                b"w0\r",
                (
                    "\r\n" + server + "\r\nw0\r\n" + "\r\n".join(table("Commanded", moving)) + "\r\n$ "
                ).encode(),
            ),
        ]
    ) as (robot, _):
        robot.connect()
        with pytest.raises(ServoError, match="Excessive lag error on axis 1") as info:
            robot.move_joint(1, 2.0)
    assert info.value.axis == 1


def test_the_point_of_control_notice_is_a_wait_surfaced_to_the_caller():
    target = (1.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    notice = "Press the PAUSE/CONTINUE button to gain robot point of control."
    seen: list[str] = []
    with scripted_robot(
        [*connect_exchanges(), w0(), say("joint 1 1.000", "", notice), *arrived(target)],
        on_notice=seen.append,
    ) as (robot, _):
        robot.connect()
        robot.move_joint(1, 1.0)
    assert seen == [notice]
    assert robot.last_notice == notice


def test_a_query_that_gets_no_prompt_times_out_then_the_link_resyncs():
    with scripted_robot([*connect_exchanges(), silent("w2"), say(""), w2(), w0()]) as (robot, _):
        robot.connect()
        with pytest.raises(DeviceTimeoutError, match="no prompt"):
            robot.where()
        assert robot.where().commanded_joints_deg == READY


def test_a_late_reply_is_skipped_by_the_resync():
    late = ("w0\r\n" + "\r\n".join(table("Commanded", READY)) + "\r\n$ ").encode()
    with scripted_robot([*connect_exchanges(), silent("w2"), raw(b"\r", late + b"\r\n$ "), w2(), w0()]) as (
        robot,
        _,
    ):
        robot.connect()
        with pytest.raises(DeviceTimeoutError):
            robot.where()
        assert robot.where().joints_deg == READY


def test_a_wrong_echo_is_a_protocol_error():
    with scripted_robot([*connect_exchanges(), raw(b"w2\r", b"w3\r\n$ ")]) as (robot, _):
        robot.connect()
        with pytest.raises(DeviceProtocolError, match="echo"):
            robot.where()


def test_output_before_the_echo_is_logged_and_its_error_remembered(caplog):
    with scripted_robot(
        [
            *connect_exchanges(),
            raw(b"speed\r", b"joint: Collision error on axis 3\r\nspeed\r\nCurrent Speed: 50% of max.\r\n$ "),
            armstat(),
        ]
    ) as (robot, _):
        robot.connect()
        assert robot.status().last_error == "joint: Collision error on axis 3"
    assert "unasked" in caplog.text


def test_stop_while_idle_sends_ctrl_z_resyncs_rereads_and_latches():
    with scripted_robot(
        [
            *connect_exchanges(),
            raw(b"\x1a", (HALT + "\r\n").encode()),
            say(""),
            w2(),
            w0(),
            w0(),
            say("joint 1 1.000"),
            *arrived((1, 0, 90, 0, 90, 0)),
        ]
    ) as (robot, port):
        robot.connect()
        robot.stop()
        assert robot.stopped
        assert robot.last_position is not None
        written = bytes(port.written)
        with pytest.raises(MotionStoppedError, match="acknowledge the stop at the station"):
            robot.move_joint(1, 1.0)
        with pytest.raises(MotionStoppedError, match="acknowledge the stop at the station"):
            robot.ready()
        with pytest.raises(MotionStoppedError, match="acknowledge the stop at the station"):
            robot.home()
        with pytest.raises(MotionStoppedError, match="not cleared by starting again"):
            robot.clear_stop()
        assert bytes(port.written) == written  # nothing sent while latched
        robot.acknowledge_stop(local_ack())
        robot.move_joint(1, 1.0)


def test_a_halt_seen_during_a_motion_latches_and_raises_motion_stopped():
    stopped = (7.5, 0.0, 90.0, 0.0, 90.0, 0.0)
    with scripted_robot(
        [
            *connect_exchanges(),
            w0(),
            say("joint 1 20.000", HALT),
            say(""),
            w2(stopped),
            w0(stopped),
        ]
    ) as (robot, _):
        robot.connect()
        with pytest.raises(MotionStoppedError, match=r"7\.500"):
            robot.move_joint(1, 20)
    assert robot.stopped
    assert robot.last_position is not None
    assert robot.last_position.commanded_joints_deg == stopped


def test_noise_after_a_motion_says_the_arm_may_have_moved():
    moved = (1.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    with scripted_robot(
        [*connect_exchanges(), w0(), say("joint 1 1.000", "\x8f\x93#\xa1"), say(""), w2(moved), w0(moved)]
    ) as (robot, _):
        robot.connect()
        with pytest.raises(
            DeviceProtocolError, match=r"(?s)non-printable.*may have moved.*commanded at \(1\.000"
        ):
            robot.move_joint(1, 1.0)


def test_rejected_motion_writes_nothing():
    with scripted_robot(connect_exchanges()) as (robot, port):
        robot.connect()
        before = bytes(port.written)
        with pytest.raises(MotionRejectedError, match="nothing was sent"):
            robot.move_joints((0, 0, 90, 0, 120, 0))
        assert bytes(port.written) == before


def test_check_move_raises_what_the_move_would_without_io():
    with scripted_robot(connect_exchanges(), safety=None) as (robot, port):
        robot.connect()
        before = bytes(port.written)
        robot.check_move((10, 0, 90, 0, 90, 0))
        with pytest.raises(MotionRejectedError, match="outside its limits"):
            robot.check_move((0, 0, 90, 0, 120, 0))
        with pytest.raises(MotionRejectedError, match="maximum step"):
            robot.check_move((40, 0, 90, 0, 90, 0))
        # a chain: each step from the previous target
        robot.check_move((50, 0, 90, 0, 90, 0), start_deg=(25, 0, 90, 0, 90, 0))
        assert bytes(port.written) == before


def test_motion_deadline_grows_with_the_move_and_falls_with_the_speed():
    with scripted_robot([*connect_exchanges(), say("speed 10"), speed_report(10)], motion=FAST_MOTION) as (
        robot,
        _,
    ):
        robot.connect()
        short = robot.motion_deadline_s(READY, (1, 0, 90, 0, 90, 0))
        long = robot.motion_deadline_s(READY, (30, 0, 90, 0, 90, 0))
        robot.set_speed(10)
        slow = robot.motion_deadline_s(READY, (30, 0, 90, 0, 90, 0))
    assert short < long < slow
    # 30 deg at 50 % of 180 deg/s (0.125 s ramps): 30/90 + 90/720 s, x 3 + the 1 s margin
    assert long == pytest.approx((30 / 90 + 90 / 720) * 3 + 1.0)


def test_before_connect_identity_is_unknown_and_check_move_needs_a_start():
    with scripted_robot([]) as (robot, port):
        assert robot.identity() == DeviceIdentity(model=None, serial=None, port="ScriptedPort", firmware=None)
        with pytest.raises(DeviceError, match=r"connect\(\) first, or pass start_deg"):
            robot.check_move(READY)
        robot.check_move((5, 0, 90, 0, 90, 0), start_deg=READY)
        robot.stop()  # not connected: latched, nothing sent
        assert robot.stopped
        assert bytes(port.written) == b""
