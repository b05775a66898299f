"""The stop latch (issue 23, item 4): released only by a local acknowledgement, kept across processes."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from drivers.crs_a465 import CrsA465
from station.devices import StopLatchedError
from station.local_ack import LocalAcknowledgement, RemoteAcknowledgementError
from tests.drivers.crs_a465.fakes import connect_exchanges, scripted_robot
from tests.local_ack import local_ack


def test_a_stop_is_not_released_by_clear_stop_nor_by_a_remote_or_forged_acknowledgement(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin)
    robot.stop()
    for attempt in (
        robot.clear_stop,
        lambda: robot.acknowledge_stop("local"),
        lambda: robot.acknowledge_stop(None),
    ):
        with pytest.raises((StopLatchedError, RemoteAcknowledgementError)):
            attempt()
        assert robot.stopped
    with pytest.raises(RemoteAcknowledgementError, match=r"10\.0\.0\.7"):
        LocalAcknowledgement.from_loopback("10.0.0.7")  # what a route must refuse for a remote client
    with pytest.raises(TypeError, match="made only by"):
        LocalAcknowledgement("loopback", "127.0.0.1", 0.0, "n")
    with pytest.raises(StopLatchedError, match="acknowledge"):
        robot.move_joint(1, 1.0)
    assert [m.kind for m in twin.motion_log] == []
    ack = local_ack()
    assert "stop()" in (robot.acknowledge_stop(ack) or "")
    robot.stop()
    with pytest.raises(RemoteAcknowledgementError, match="used already"):
        robot.acknowledge_stop(ack)  # an acknowledgement is good once
    robot.acknowledge_stop(local_ack())
    robot.move_joint(1, 1.0)


def test_a_controller_error_during_a_motion_latches(make_twin, robot_on):
    twin = make_twin(time_scale=1.0)
    robot = robot_on(twin)
    twin.inject("servo@2:Excessive lag error on axis 1")
    with pytest.raises(Exception, match="Excessive lag"):
        robot.move_joint(1, 20.0)
    assert robot.stopped
    assert "Excessive lag" in (robot.latch_reason or "")
    with pytest.raises(StopLatchedError):
        robot.move_joint(1, -1.0)


def test_the_latch_outlives_the_process_in_its_latch_file(tmp_path: Path):
    latch = tmp_path / "robot-stop-latch.json"
    with scripted_robot(connect_exchanges(), latch_file=latch) as (robot, _):
        robot.connect()
        robot.close()
        robot.stop()  # not connected: nothing sent, latched all the same
    assert latch.exists()
    again = CrsA465("loop://", latch_file=latch)  # a new process's driver
    assert again.stopped
    with pytest.raises(StopLatchedError, match=r"stop\(\) from the host"):
        again.move_joint(1, 1.0)
    again.acknowledge_stop(local_ack())
    assert not latch.exists()
    assert not CrsA465("loop://", latch_file=latch).stopped


def test_a_long_running_driver_follows_an_acknowledgement_made_by_another_process(make_twin, tmp_path: Path):
    """The service's driver stays open across sessions: ``station robot --config F acknowledge`` at the
    station's terminal (another process, another driver) releases it at its next connect; a stop that
    other process latched reaches it the same way."""
    twin = make_twin()
    latch = tmp_path / "robot-stop-latch.json"
    service = CrsA465(twin.port, latch_file=latch)
    service.connect()
    try:
        service.stop()
        assert service.stopped
        terminal = CrsA465("loop://", latch_file=latch)  # the terminal's own process
        assert terminal.stopped
        terminal.acknowledge_stop(local_ack())
        assert service.stopped  # until it reads the arm again
        service.connect()
        assert not service.stopped
        service.move_joint(1, 1.0)  # moves again
        assert [m.kind for m in twin.motion_log]

        CrsA465("loop://", latch_file=latch).stop()  # latched elsewhere: followed too
        service.connect()
        assert service.stopped
        with pytest.raises(StopLatchedError):
            service.move_joint(1, -1.0)
    finally:
        service.close()


def test_a_terminal_acknowledgement_needs_a_terminal_that_is_not_an_ssh_login():
    master, slave = os.openpty()
    try:
        with os.fdopen(slave, "r", closefd=True) as tty:
            ack = LocalAcknowledgement.from_terminal(tty, environ={})
            assert ack.source == "terminal"
            with pytest.raises(RemoteAcknowledgementError, match="SSH"):
                LocalAcknowledgement.from_terminal(tty, environ={"SSH_CONNECTION": "10.0.0.7 5 10.0.0.2 22"})
    finally:
        os.close(master)
    with open(os.devnull) as not_a_tty, pytest.raises(RemoteAcknowledgementError, match="not a terminal"):
        LocalAcknowledgement.from_terminal(not_a_tty, environ={})
