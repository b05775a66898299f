"""Arrival detection and the readings it leaves behind, against recorded exchanges.

While the arm moves the driver polls ``w0`` alone; once ``w0`` equals the target it reads armstat (where
the shell has it) and ``w2``: arrived when that ``w2`` is within the gross tolerance and either armstat
showed every axis done or ``w2`` is within one count of the previous poll's. The readings that proved an
arrival stand for ``where()`` and for the next move's start until something is sent or ``reuse_s`` passes.
"""

from __future__ import annotations

from typing import Any

import pytest

from drivers.crs_a465 import CrsA465, MotionSettings, ShellProfile
from tests.drivers.crs_a465.conftest import FAST_LINK
from tests.drivers.crs_a465.fakes import (
    FAST_MOTION,
    READY,
    ScriptedPort,
    armstat,
    arrived,
    connect_exchanges,
    raw,
    say,
    scripted_robot,
    speed_report,
    w0,
    w2,
)
from tests.local_ack import local_ack

TARGET = (1.0, 0.0, 90.0, 0.0, 90.0, 0.0)
HALT = "/sbin/robotsrv: ^Z detected - halting robot..."


def test_where_right_after_an_arrival_answers_from_its_readings_without_asking_again():
    attained = (1.004, 0.0, 90.0, 0.0, 90.0, 0.0)
    with scripted_robot(
        [
            *connect_exchanges(),
            w0(),
            say("joint 1 1.000"),
            w0(TARGET),
            armstat(),
            w2(attained),
            speed_report(),  # status() sends something: the arrival's readings no longer stand for now
            armstat(),
            w2(attained),
            w0(TARGET),
        ]
    ) as (robot, port):
        robot.connect()
        robot.move_joint(1, 1.0)
        sent = bytes(port.written)
        pos = robot.where()
        assert bytes(port.written) == sent  # nothing sent
        assert pos.joints_deg == attained
        assert pos.commanded_joints_deg == TARGET
        robot.status()
        assert robot.where().joints_deg == attained  # read again: w2, w0


def test_with_reuse_off_where_and_the_next_move_read_the_controller():
    no_reuse = FAST_MOTION.model_copy(update={"reuse_s": 0.0})
    with scripted_robot(
        [
            *connect_exchanges(),
            w0(),
            say("joint 1 1.000"),
            *arrived(TARGET),
            w2(TARGET),
            w0(TARGET),
            w0(TARGET),
            say("joint 1 -1.000"),
            *arrived(READY),
        ],
        motion=no_reuse,
    ) as (robot, _):
        robot.connect()
        robot.move_joint(1, 1.0)
        assert robot.where().commanded_joints_deg == TARGET
        robot.move_joint(1, -1.0)


def test_the_next_move_starts_from_the_arrivals_w0_but_a_stop_forgets_it():
    with scripted_robot(
        [
            *connect_exchanges(),
            w0(),
            say("joint 1 1.000"),
            *arrived(TARGET),
            say("joint 1 -1.000"),  # no w0 before it: the arrival's w0 is the start
            *arrived(READY),
            raw(b"\x1a", (HALT + "\r\n").encode()),
            say(""),
            w2(),
            w0(),
            w0(),  # after the stop the next move reads where it starts
            say("joint 1 1.000"),
            *arrived(TARGET),
        ]
    ) as (robot, _):
        robot.connect()
        robot.move_joint(1, 1.0)
        robot.move_joint(1, -1.0)
        robot.stop()
        robot.acknowledge_stop(local_ack())
        robot.move_joint(1, 1.0)


def test_armstat_not_done_falls_back_to_w2_still_over_two_polls():
    moving = (0.99, 0.0, 90.0, 0.0, 90.0, 0.0)  # 11 counts short: still moving
    settled = (1.001, 0.0, 90.0, 0.0, 90.0, 0.0)
    with scripted_robot(
        [
            *connect_exchanges(),
            w0(),
            say("joint 1 1.000"),
            w0(TARGET),
            armstat(moving=[1]),
            w2(moving),
            armstat(moving=[1]),
            w2(settled),  # changed since the last poll: not still yet
            armstat(moving=[1]),
            w2(settled),  # within one count of the previous poll: arrived, whatever armstat says
        ]
    ) as (robot, _):
        robot.connect()
        robot.move_joint(1, 1.0)
    assert robot.last_arrival is not None
    assert robot.last_arrival.actual_deg == settled


def test_without_armstat_arrival_needs_w2_still_over_two_polls():
    shell = ShellProfile.system(has_armstat=False)
    with scripted_robot(
        [say(""), speed_report(), w2(), w0(), w0(), say("joint 1 1.000"), w0(TARGET), w2(TARGET), w2(TARGET)],
        shell=shell,
    ) as (robot, _):
        robot.connect()
        robot.move_joint(1, 1.0)
    assert robot.last_arrival is not None
    assert robot.last_arrival.actual_deg == TARGET


class Clock:
    """A clock that moves only when the driver sleeps or the (slow) line carries a command."""

    def __init__(self) -> None:
        self.t = 0.0
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.t += seconds


class SlowLine(ScriptedPort):
    """Each command and its reply take ``reply_s`` on the line; records when each command was sent."""

    def __init__(self, exchanges: Any, clock: Clock, reply_s: float) -> None:
        super().__init__(exchanges)
        self.clock = clock
        self.reply_s = reply_s
        self.sent_at: list[tuple[bytes, float]] = []

    def read(self, size: int = 1) -> bytes:
        if not self.in_waiting:
            self.clock.t += self.timeout or 0.02  # a read that waits for nothing takes its timeout
        return super().read(size)

    def write(self, data: bytes) -> int:
        self.sent_at.append((bytes(data), self.clock.t))
        self.clock.t += self.reply_s
        return super().write(data)


def test_a_poll_that_would_straddle_the_expected_end_of_the_motion_waits_for_it():
    # joint 1 by 10 deg at 50 %: 90 deg/s, 720 deg/s^2, about 0.2357 s by the timing model; each reply
    # takes 0.15 s on the line: a w0 sent at 0.15 s after the handover would still be on the line at the
    # end, so the driver sends it at the end instead and finds the arm there
    clock = Clock()
    target = (10.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    moving = (4.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    exchanges = [
        *connect_exchanges(),
        w0(),
        say("joint 1 10.000"),
        w0(moving),
        w0(target),
        armstat(),
        w2(target),
    ]
    port = SlowLine(exchanges, clock, reply_s=0.15)
    robot = CrsA465(
        port,
        link=FAST_LINK,
        motion=MotionSettings(deadline_margin_s=1.0, stall_timeout_s=1.0, poll_interval_s=0.02),
        clock=clock,
        sleep=clock.sleep,
    )
    robot.connect()
    robot.move_joint(1, 10.0)
    port.assert_done()
    handed = next(t for data, t in port.sent_at if data.startswith(b"joint")) + 0.15
    polls = [t - handed for data, t in port.sent_at if data == b"w0\r"][-2:]
    assert polls[0] == pytest.approx(0.0)  # the first poll goes at once (it can end before the motion)
    assert polls[1] == pytest.approx(0.2357, abs=1e-3)  # the second at the model's end, not at 0.15 s
