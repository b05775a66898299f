"""Every fault the twin can inject, met by the driver over a real pty: typed errors, then recovery."""

from __future__ import annotations

import os

import pytest

from drivers.crs_a465 import ArmPowerOffError, LinkSettings, RaplExceptionError
from sim.controller import Fault, FaultKind
from station.devices import DeviceConnectionError, DeviceProtocolError, DeviceTimeoutError
from tests.drivers.crs_a465.fakes import READY


def test_garbled_reply_is_a_protocol_error_and_the_next_command_works(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin)
    twin.inject("garble@1")
    with pytest.raises(DeviceProtocolError, match="non-printable"):
        robot.where()
    assert robot.where().commanded_joints_deg == READY


def test_garbled_reply_to_a_motion_is_an_error_though_the_arm_moved(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin)
    twin.inject("garble@2")  # w0, then the joint move
    with pytest.raises(DeviceProtocolError):
        robot.move_joint(3, -4.0)
    assert robot.where().commanded_joints_deg[2] == 86.0  # the controller did move: re-read, never assume


def test_dropped_reply_times_out_and_the_link_resyncs(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin)
    twin.inject("drop@1")
    with pytest.raises(DeviceTimeoutError, match="no prompt"):
        robot.status()
    assert robot.status().speed_pct == 50.0


def test_dropped_reply_of_a_motion_that_did_not_run(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin)
    twin.inject(Fault(kind=FaultKind.DROP, at=2, execute=False))
    with pytest.raises(DeviceTimeoutError):
        robot.move_joint(1, 2.0)
    assert robot.where().commanded_joints_deg == READY


RAPL_POWER = "Process 193: exception raised (code = 'Arm power is OFF')\n  in module './joint' at joint.r3:65"
RAPL_OTHER = "Process 7: exception raised (code = 'Servo fault')\n  in module './joint' at joint.r3:9"


@pytest.mark.parametrize(
    ("text", "error"),
    [
        ("joint: 007 Arm power is OFF", ArmPowerOffError),
        (RAPL_POWER, ArmPowerOffError),
        (RAPL_OTHER, RaplExceptionError),
    ],
)
def test_controller_error_on_the_nth_command(make_twin, robot_on, text, error):
    twin = make_twin()
    robot = robot_on(twin)
    twin.inject(Fault(kind=FaultKind.ERROR, on="joint 2", text=text))  # whatever polls came before it
    with pytest.raises(error):
        robot.move_joints((1.0, 1.0, 90.0, 0.0, 90.0, 0.0))
    assert robot.where().commanded_joints_deg == (1.0, 0.0, 90.0, 0.0, 90.0, 0.0)  # stopped at the error
    assert robot.status().last_error is not None


def test_disconnect_raises_and_reconnect_rereads_the_arm(make_twin, robot_on):
    twin = make_twin(link="auto")
    robot = robot_on(twin)
    robot.move_joint(1, 3.0)
    twin.inject("disconnect@1")
    with pytest.raises(DeviceConnectionError, match="lost the link"):
        robot.status()  # (a where() right after the move may answer from the arrival's readings)
    assert not robot.is_connected
    with pytest.raises(DeviceConnectionError, match="connect"):
        robot.where()
    with pytest.raises(DeviceConnectionError, match="cannot open"):
        robot.connect()  # the port is gone while unplugged
    twin.replug()
    robot.connect()
    assert robot.last_position is not None
    assert robot.last_position.commanded_joints_deg[0] == 3.0


def test_disconnect_with_automatic_replug(make_twin, robot_on):
    twin = make_twin(link="auto")
    robot = robot_on(twin)
    twin.inject(Fault(kind=FaultKind.DISCONNECT, replug_after_s=0.05))
    with pytest.raises(DeviceConnectionError):
        robot.status()
    assert twin.wait_plugged(timeout_s=5.0)
    assert os.path.exists(twin.port)
    robot.connect()
    assert robot.status().speed_pct == 50.0


def test_slow_reply_within_the_timeout_is_fine(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin)
    twin.inject(Fault(kind=FaultKind.SLOW, delay_s=0.05))
    assert robot.status().speed_pct == 50.0


def test_slow_reply_beyond_the_timeout_times_out_then_the_late_reply_is_skipped(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin, link=LinkSettings(reply_timeout_s=0.4, resync_quiet_s=0.0))
    twin.inject(Fault(kind=FaultKind.SLOW, delay_s=0.5))  # comes 0.1 s into the resync's 0.4 s
    with pytest.raises(DeviceTimeoutError):
        robot.where()
    assert robot.where().commanded_joints_deg == READY
