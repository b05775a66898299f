"""Each defect the firmware image exposed, as a test (the issue's first list), against an independent
emulator of the firmware's system shell (``firmware_emulator``), not the twin.

Every test here failed on the driver as it was before it was made to speak the firmware's dialect.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from drivers.crs_a465 import CrsA465, LinkSettings
from station.cli import main
from station.devices import DeviceError, DeviceProtocolError, DeviceTimeoutError, MotionStoppedError
from tests.drivers.crs_a465.firmware_emulator import READY, FirmwareEmulator

LINK = LinkSettings(reply_timeout_s=1.0, resync_quiet_s=0.02)


@pytest.fixture
def emulator() -> Iterator[FirmwareEmulator]:
    emu = FirmwareEmulator()
    yield emu
    emu.close()


@pytest.fixture
def robot(emulator: FirmwareEmulator) -> Iterator[CrsA465]:
    r = CrsA465(emulator.path, link=LINK)
    r.connect()
    yield r
    r.close()


def test_position_tables_in_the_firmwares_layout_are_read(robot: CrsA465) -> None:
    p = robot.where()
    assert p.joints_deg == READY
    assert p.commanded_joints_deg == READY
    assert p.world_mm_deg == (400.0, 0.0, 500.0, 0.0, 90.0, 0.0)  # WORLD's values on the WORLD line


def test_a_motion_returns_only_once_the_arm_has_arrived(emulator: FirmwareEmulator, robot: CrsA465) -> None:
    robot.move_joint(2, 5.0)  # the prompt comes back at once; the arm needs 0.3 s
    assert not emulator.moving()
    assert robot.where().joints_deg == (0.0, 5.0, 90.0, 0.0, 90.0, 0.0)
    robot.move_joints((1.0, 5.0, 90.0, 0.0, 90.0, 0.0))
    assert not emulator.moving()
    robot.ready()
    assert not emulator.moving()
    assert robot.where().joints_deg == READY


@pytest.mark.parametrize(
    ("command", "text"),
    [("joint", "Joint 1 limit"), ("home", "Homing failed"), ("ready", "ready: something new")],
)
def test_unrecognised_output_after_a_motion_is_an_error(
    emulator: FirmwareEmulator, robot: CrsA465, command: str, text: str
) -> None:
    emulator.replace[command] = [text]
    action = {"joint": lambda: robot.move_joint(1, 5.0), "home": robot.home, "ready": robot.ready}[command]
    with pytest.raises(DeviceError, match=text.replace("(", r"\(")):
        action()


def test_armstat_on_the_system_shell_reports_power_homing_and_motion(emulator: FirmwareEmulator) -> None:
    emulator.duration_s = 5.0
    robot = CrsA465(emulator.path, link=LINK)
    try:
        robot.connect()
        status = robot.status()
        assert (status.power, status.homed, status.moving) == (True, True, False)
        emulator.power = False
        status = robot.status()  # power off is a state to report, not an exception
        assert (status.power, status.homed) == (False, True)
        emulator.power = True
        emulator._move_to([10.0, 0.0, 90.0, 0.0, 90.0, 0.0])  # moved from the pendant
        assert robot.status().moving is True
    finally:
        robot.close()


def test_stop_sends_the_halt_key_latches_and_leaves_nothing_in_the_next_line(
    emulator: FirmwareEmulator, robot: CrsA465
) -> None:
    robot.move_joint(1, 1.0)
    robot.stop()  # between two motions: must not be lost
    assert emulator.halted == 1
    with pytest.raises(MotionStoppedError):
        robot.move_joint(1, 1.0)
    assert robot.where().commanded_joints_deg[0] == 1.0
    assert all(not any(ord(c) < 0x20 for c in line) for line in emulator.lines)  # no '\x03w2'


@pytest.mark.parametrize(("signum", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_in_station_robot_stops_the_arm_and_says_where_it_is(
    emulator: FirmwareEmulator, signum: int, code: int
) -> None:
    emulator.duration_s = 20.0
    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys; from station.cli import main; sys.exit(main())",
         "robot", "--port", emulator.path, "--json", "joint", "1", "30"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        for _ in range(3000):  # until the arm moves (the child starts Python, connects, sends the joint)
            if emulator.moving() or proc.poll() is not None:
                break
            time.sleep(0.01)
        assert emulator.moving(), proc.stderr.read() if proc.poll() is not None and proc.stderr else ""
        proc.send_signal(signum)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == code, err
    assert emulator.halted == 1
    assert not emulator.moving()
    assert "stop sent; the arm is at joints" in err
    assert 0.0 < json.loads(out)["joints_deg"][0] < 30.0


def test_a_lost_reply_to_a_motion_fails_by_a_deadline_derived_from_the_move(
    emulator: FirmwareEmulator, robot: CrsA465
) -> None:
    emulator.drop.add("joint")
    with pytest.raises(DeviceTimeoutError, match=r"within 5\.22 s") as info:
        robot.move_joint(1, 1.0)  # 1 deg at 50 %: 0.075 s expected, x 3 + 5 s
    assert "may have moved" in str(info.value)


def test_a_garbled_reply_to_a_motion_that_ran_says_the_arm_may_have_moved(
    emulator: FirmwareEmulator, robot: CrsA465
) -> None:
    emulator.garble.add("joint")
    with pytest.raises(
        DeviceProtocolError,
        match=r"(?s)non-printable.*may have moved after 'joint 1 2\.000': it is now commanded at \(\d",
    ):
        robot.move_joint(1, 2.0)


def test_a_second_opener_gets_an_in_use_error(emulator: FirmwareEmulator, robot: CrsA465) -> None:
    second = CrsA465(emulator.path, link=LINK)
    with pytest.raises(DeviceError, match="in use"):
        second.connect()
    assert robot.where().joints_deg == READY


def test_a_bad_option_value_exits_2_with_one_line(
    capsys: pytest.CaptureFixture[str], emulator: FirmwareEmulator
) -> None:
    code = main(["robot", "--port", emulator.path, "--timeout", "-1", "status"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1
    assert "--timeout" in err
    assert emulator.lines == []
