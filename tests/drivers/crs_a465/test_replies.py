"""Reply parsing in one place: the doc's table, speed and power texts; noise never becomes a number."""

from __future__ import annotations

import pytest

from drivers.crs_a465 import (
    ArmPowerOffError,
    AxisLimpError,
    CollisionError,
    IllegalSpeedError,
    JointLimitError,
    NotHomedError,
    NotOnlineError,
    OutOfReachError,
    PointOfControlError,
    UnknownCommandError,
)
from drivers.crs_a465._errors import find_error
from drivers.crs_a465._replies import parse_armstat, parse_position, parse_speed
from station.devices import DeviceProtocolError
from tests.drivers.crs_a465.fakes import table

# The protocol doc's example, verbatim (its values only show the format).
DOC_TABLE = """Commanded Position :
          Axis 1/7   Axis 2/8     Axis 3     Axis 4     Axis 5     Axis 6
PULSES      +11111     -5833   +100000         +0     +25000         +0
              +0         +0
JOINTS     +10.000    -5.250     +90.000     +0.000    +45.000     +0.000
              +0.000     +0.000
          X/TrackX   Y/TrackY          Z      Z-Rot      Y-Rot      X-Rot
WORLD         (mm)       (mm)       (mm)      (deg)      (deg)      (deg)
          +400.000     +0.000   +500.000     +0.000    +90.000     +0.000""".splitlines()


def test_parses_the_protocol_docs_table():
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
    with pytest.raises(DeviceProtocolError, match="ends"):
        parse_position(DOC_TABLE[:6], expect="commanded", command="w0")
    with pytest.raises(DeviceProtocolError, match="after the table"):
        parse_position([*DOC_TABLE, "extra"], expect="commanded", command="w0")


def test_parses_speed():
    assert parse_speed(["Current Speed: 50% of max."]) == 50.0
    with pytest.raises(DeviceProtocolError):
        parse_speed(["Current Speed: 5O% of max."])
    with pytest.raises(DeviceProtocolError):
        parse_speed([])


def test_parses_armstat_and_leaves_what_is_not_said_unknown():
    stat = parse_armstat(["Robot arm is of type A465", "Arm Power is ON", "Robot is calibrated and homed"])
    assert (stat.power, stat.homed, stat.arm_type) == (True, True, "A465")
    assert parse_armstat(["Arm Power is OFF"]).homed is None
    with pytest.raises(DeviceProtocolError):
        parse_armstat(["nothing useful"])


@pytest.mark.parametrize(
    ("line", "error", "code", "axis"),
    [
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
    found = find_error([line], "cmd")
    assert type(found) is error
    assert (found.code, found.axis, found.controller_text) == (code, axis, line)
    assert found.hint in str(found)


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
