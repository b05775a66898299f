"""Reply parsing in one place: the firmware's literal layouts, the application shell's assumed one, speed,
armstat and the error table; noise never becomes a number."""

from __future__ import annotations

import pytest

from drivers.crs_a465 import (
    ArmPowerOffError,
    AxisLimpError,
    AxisLockedError,
    CollisionError,
    ControllerBusyError,
    ControllerUsageError,
    CrsControllerError,
    EncoderAlarmError,
    HomingError,
    IllegalSpeedError,
    JointLimitError,
    LockedOutError,
    MotionAbortedError,
    MotionFaultError,
    NotHomedError,
    NotOnlineError,
    OutOfReachError,
    PointOfControlError,
    ServoError,
    StanceError,
    UnknownCommandError,
    UnmappedCodeError,
)
from drivers.crs_a465._errors import find_error
from drivers.crs_a465._replies import parse_armstat, parse_position, parse_speed
from station.devices import DeviceProtocolError
from tests.drivers.crs_a465.fakes import table

# The firmware's w0 layout, verbatim from its format strings (DIALECT.md, "confirmed by the firmware").
FIRMWARE_W0 = """Commanded Position :

          Axis 1/7   Axis 2/8     Axis 3     Axis 4     Axis 5     Axis 6
PULSES      +13889     -23611     +36667      -2222     +26389      +4514
                +0         +0

          Axis 1/7   Axis 2/8     Axis 3     Axis 4     Axis 5     Axis 6
JOINTS     +12.500    -21.250    +33.000     -4.000    +47.500     +8.125
            +0.000     +0.000

          X/TrackX   Y/TrackY          Z      Z-Rot      Y-Rot      X-Rot
WORLD     +400.000    +12.000   +500.000    +12.500    +90.000     +0.000
            +0.000     +0.000""".splitlines()

FIRMWARE_ARMSTAT = """
Robot arm is of type A465
Arm power is ON      Robot is calibrated and homed
Units are Metric     Online is OFF
Physical stance: free free free


Current Tool Transform is: 
tx=0.00000, ty=0.00000, tz=0.00000, yaw=0.00000, pitch=0.00000, roll=0.00000

Current Base Transform is: 
wx=0.00000, wy=0.00000, wz=0.00000, xrot=0.00000, yrot=0.00000, zrot=0.00000

Axis    locked   done   limped   homed
 1        N       Y       N       Y
 2        N       Y       N       Y
 3        N       N       N       Y
 4        N       Y       N       Y
 5        N       Y       N       Y
 6        N       Y       N       Y
""".splitlines()  # noqa: W291 - the firmware's trailing space after "is:"

# The application shell's layout: kept from older notes, no public text of it is known [assumed].
DOC_TABLE = """Commanded Position :
          Axis 1/7   Axis 2/8     Axis 3     Axis 4     Axis 5     Axis 6
PULSES      +11111     -5833   +100000         +0     +25000         +0
              +0         +0
JOINTS     +10.000    -5.250     +90.000     +0.000    +45.000     +0.000
              +0.000     +0.000
          X/TrackX   Y/TrackY          Z      Z-Rot      Y-Rot      X-Rot
WORLD         (mm)       (mm)       (mm)      (deg)      (deg)      (deg)
          +400.000     +0.000   +500.000     +0.000    +90.000     +0.000""".splitlines()


def test_parses_the_firmwares_own_layout():
    report = parse_position(FIRMWARE_W0, expect="commanded", command="w0")
    assert report.pulses == (13889, -23611, 36667, -2222, 26389, 4514)
    assert report.joints_deg == (12.5, -21.25, 33.0, -4.0, 47.5, 8.125)
    assert report.world_mm_deg == (400.0, 12.0, 500.0, 12.5, 90.0, 0.0)
    assert (report.track_pulses, report.track_deg, report.track_world) == ((0, 0), (0.0, 0.0), (0.0, 0.0))


def test_the_actual_table_has_the_same_layout():
    lines = ["Actual Position :", *FIRMWARE_W0[1:]]
    assert parse_position(lines, expect="actual", command="w2").joints_deg[5] == 8.125


@pytest.mark.parametrize(
    "variant",
    [
        pytest.param(lambda lines: [line for line in lines if line.strip()], id="no blank lines"),
        pytest.param(lambda lines: [line for line in lines if line.strip() != "+0.000     +0.000"
                                    and line.strip() != "+0         +0"], id="no axes 7-8 rows"),
        pytest.param(lambda lines: [x for line in lines for x in ([line, ""] if line.strip() else [line])],
                     id="extra blank lines"),
        pytest.param(lambda lines: [line.replace("JOINTS ", "JOINTS\n  ") for line in lines],
                     id="values below"),
    ],
)  # fmt: skip
def test_labelled_rows_tolerate_layout_variants(variant):
    lines = "\n".join(variant(list(FIRMWARE_W0))).split("\n")
    report = parse_position(lines, expect="commanded", command="w0")
    assert report.joints_deg == (12.5, -21.25, 33.0, -4.0, 47.5, 8.125)
    assert report.world_mm_deg == (400.0, 12.0, 500.0, 12.5, 90.0, 0.0)


def test_parses_the_application_shells_assumed_table():
    report = parse_position(DOC_TABLE, expect="commanded", command="w0")
    assert report.pulses == (11111, -5833, 100000, 0, 25000, 0)
    assert report.joints_deg == (10.0, -5.25, 90.0, 0.0, 45.0, 0.0)
    assert report.track_pulses == (0, 0)
    assert report.track_deg == (0.0, 0.0)
    assert report.world_mm_deg == (400.0, 0.0, 500.0, 0.0, 90.0, 0.0)


def test_column_spacing_does_not_matter():
    squeezed = [" ".join(line.split()) for line in table("Actual", (1, 2, 3, 4, 5, 6))]
    assert parse_position(squeezed, expect="actual", command="w2").joints_deg == (1, 2, 3, 4, 5, 6)


def test_a_table_of_the_other_kind_is_refused():
    with pytest.raises(DeviceProtocolError, match="Actual Position"):
        parse_position(DOC_TABLE, expect="actual", command="w2")


@pytest.mark.parametrize(
    ("row", "mangled"),
    [
        (4, "JOINTS     +10.000    -5.250     +90.0#0     +0.000    +45.000     +0.000"),  # noise in a number
        (4, "JOINTS     +10.000    -5.250     +90.000     +0.000    +45.000"),  # a value lost
        (4, "JOINTS     +10        -5.250     +90.000     +0.000    +45.000     +0.000"),  # wrong format
        (2, "PULSES      +11111     -5833   +100000         +0     +25\xe000         +0"),  # bit 7 set
        (8, "          +400.000     +0.000"),  # world row cut short
    ],
)
def test_a_garbled_row_is_a_protocol_error(row, mangled):
    lines = list(DOC_TABLE)
    lines[row] = mangled
    with pytest.raises(DeviceProtocolError):
        parse_position(lines, expect="commanded", command="w0")


def test_a_truncated_or_padded_table_is_a_protocol_error():
    with pytest.raises(DeviceProtocolError, match="ends before its"):
        parse_position(DOC_TABLE[:6], expect="commanded", command="w0")
    with pytest.raises(DeviceProtocolError, match="ends before its WORLD"):
        parse_position(FIRMWARE_W0[:9], expect="commanded", command="w0")
    with pytest.raises(DeviceProtocolError, match="extra"):
        parse_position([*FIRMWARE_W0, "extra"], expect="commanded", command="w0")
    with pytest.raises(DeviceProtocolError, match="unexpected JOINTS"):
        parse_position([*FIRMWARE_W0, FIRMWARE_W0[7]], expect="commanded", command="w0")


def test_parses_speed():
    assert parse_speed(["Current Speed: 50% of max."]) == 50.0
    assert parse_speed(["Current speed is 25"]) == 25.0  # the application shell's form
    with pytest.raises(DeviceProtocolError):
        parse_speed(["Current Speed: 5O% of max."])
    with pytest.raises(DeviceProtocolError):
        parse_speed([])


def test_parses_the_firmwares_armstat():
    stat = parse_armstat(FIRMWARE_ARMSTAT)
    assert (stat.power, stat.calibrated, stat.homed, stat.arm_type) == (True, True, True, "A465")
    assert [a.done for a in stat.axes] == [True, True, False, True, True, True]
    assert stat.moving is True
    assert all(a.homed and not a.locked and not a.limped for a in stat.axes)


@pytest.mark.parametrize(
    ("line", "power", "calibrated", "homed"),
    [
        ("Arm power is OFF     Robot is calibrated and homed", False, True, True),
        ("Arm power is ON      Robot is calibrated", True, True, False),
        ("Arm power is ON      Robot is not homed", True, None, False),
        ("Arm power is OFF     Robot is not calibrated", False, False, False),
    ],
)
def test_armstat_power_and_homing_share_one_line(line, power, calibrated, homed):
    lines = list(FIRMWARE_ARMSTAT)
    lines[2] = line
    stat = parse_armstat(lines)
    assert (stat.power, stat.calibrated, stat.homed) == (power, calibrated, homed)
    assert find_error(lines, "armstat") is None  # a power-off report is a state, not an error


def test_parses_armstat_and_leaves_what_is_not_said_unknown():
    stat = parse_armstat(["Robot arm is of type A465", "Arm Power is ON", "Robot is calibrated and homed"])
    assert (stat.power, stat.homed, stat.arm_type) == (True, True, "A465")
    assert stat.moving is None  # no axis table: motion unknown
    assert parse_armstat(["Arm Power is OFF"]).homed is None
    with pytest.raises(DeviceProtocolError):
        parse_armstat(["nothing useful"])
    with pytest.raises(DeviceProtocolError, match="homing state"):
        parse_armstat(["Arm power is ON      Robot is somewhere"])


@pytest.mark.parametrize(
    ("line", "error", "code", "axis"),
    [
        ("joint: Joint 2 limit exceeded", JointLimitError, None, 2),
        ("ready: Location out of reach", OutOfReachError, None, None),
        ("joint: Axis 4 is locked", AxisLockedError, None, 4),
        ("joint: Motion error", MotionFaultError, None, None),
        ("ready: Abort in progress", MotionAbortedError, None, None),
        ("home: Homing sequence error", HomingError, None, None),
        ("ready: Cannot perform requested motion in current stance", StanceError, None, None),
        ("joint: Axis 3 velocity limit exceeded", MotionFaultError, None, 3),
        ("joint: Halt() command invoked", MotionAbortedError, None, None),
        ("joint: This command has been locked out", LockedOutError, None, None),
        ("joint: Axis 2 was too far from the expected position", MotionFaultError, None, 2),
        ("/sbin/robotsrv: Excessive lag error on axis 5 (error code 0x7021)", ServoError, None, 5),
        (
            "/sbin/robotsrv: Axis 1 encoder alarm -- batteries may be low (error code 0x7033)",
            EncoderAlarmError,
            None,
            1,
        ),
        ("joint: Amp disabled on axis 6", ServoError, None, 6),
        ("joint: access denied", PointOfControlError, None, None),
        ("joint: resource temporarily unavailable", ControllerBusyError, None, None),
        ("shell: bogus: not found", UnknownCommandError, None, None),
        ("joint: error code 4:12:0:7", UnmappedCodeError, None, None),
        ("Invalid axis '9'", ControllerUsageError, None, None),
        ("speed: invalid speed '150'", IllegalSpeedError, None, None),
        ("home: illegal axis number '9'", ControllerUsageError, None, None),
        ("joint: Something the table does not have", CrsControllerError, None, None),
        ("joint: 001 Joint 3 limit exceeded", JointLimitError, 1, 3),
        ("003 Location out of reach", OutOfReachError, 3, None),
        ("004 Axis 5 is limp", AxisLimpError, 4, 5),
        ("005 Not homed or not calibrated", NotHomedError, 5, None),
        ("007 Arm power is OFF", ArmPowerOffError, 7, None),
        ("speed: 015 Illegal speed chosen", IllegalSpeedError, 15, None),
        ("004 Collision error on axis 2", CollisionError, 4, 2),
        ("Press the PAUSE/CONTINUE button to gain robot point of control.", PointOfControlError, None, None),
        ("Robot must be in online mode for this command.", NotOnlineError, None, None),
        ("error: Unrecognized command.", UnknownCommandError, None, None),
    ],
)
def test_maps_each_controller_error_text(line, error, code, axis):
    found = find_error([line], "joint 1 5")
    assert found is not None
    assert type(found) is error
    assert (found.code, found.axis, found.controller_text) == (code, axis, line)
    assert found.hint in str(found)


def test_a_usage_line_is_kept_with_its_error():
    found = find_error(["Invalid distance 'x'", "Usage: joint joint distance"], "joint 1 x")
    assert isinstance(found, ControllerUsageError)
    assert found.controller_text == "Invalid distance 'x' Usage: joint joint distance"


def test_a_power_report_is_not_an_error():
    assert find_error(["Arm Power is OFF", "Current Speed: 50% of max."]) is None


def test_a_rapl_exception_keeps_its_module_line_and_maps_its_code():
    found = find_error(
        [
            "Process 193: exception raised (code = 'Arm power is OFF')",
            "  in module './getrotspd' at getrotspd.r3:65",
        ]
    )
    assert isinstance(found, ArmPowerOffError)
    assert "getrotspd.r3:65" in found.controller_text
