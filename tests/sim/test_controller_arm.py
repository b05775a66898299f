"""The twin's arm model on an injected clock: trapezoidal timing, interpolation, attained-position error."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sim._controller_arm import Arm, ArmError, ArmParameters, trapezoid_fraction, trapezoid_time
from sim._controller_shell import Shell
from station.kinematics import Kinematics

READY = (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def make_arm(clock: Clock, *, seed: int = 0, time_scale: float = 1.0, **overrides: object) -> Arm:
    values: dict[str, object] = {
        "max_speed_deg_s": (180.0, 180.0, 180.0, 172.0, 172.0, 172.0),
        "accel_deg_s2": (720.0, 720.0, 720.0, 1430.0, 1430.0, 1430.0),
        "counts_per_deg": (400000 / 360,) * 3 + (200000 / 360,) * 3,
        "repeat_sigma_deg": (0.0,) * 6,
        "systematic_deg": (0.0,) * 6,
        "backlash_deg": (0.0,) * 6,
        "home_pose_deg": (0.0,) * 6,
        "ready_pose_deg": READY,
        "start_pose_deg": READY,
        "homing_extra_s": 2.0,
        "time_scale": time_scale,
    }
    values.update(overrides)
    params = ArmParameters(**values)  # type: ignore[arg-type]
    return Arm(
        params,
        Kinematics(),
        power=True,
        homed=True,
        speed_pct=100,
        rng=np.random.default_rng(seed),
        clock=clock,
    )


def test_trapezoid_time_of_the_docs_example():
    # 50 deg of joint 1 at 100%: 50/180 + 180/720 = 0.528 s (the doc: "about 0.5 s")
    assert trapezoid_time(50.0, 180.0, 720.0) == pytest.approx(50 / 180 + 0.25)
    assert trapezoid_time(10.0, 180.0, 720.0) == pytest.approx(2 * (10 / 720) ** 0.5)  # triangular
    assert trapezoid_time(0.0, 180.0, 720.0) == 0.0


@pytest.mark.parametrize("distance", [5.0, 45.0, 120.0])
def test_trapezoid_fraction_is_monotonic_from_0_to_1_and_symmetric(distance):
    total = trapezoid_time(distance, 180.0, 720.0)
    t = np.linspace(0, total, 101)
    s = np.array([trapezoid_fraction(x, distance, 180.0, 720.0) for x in t])
    assert s[0] == 0.0
    assert s[-1] == 1.0
    assert np.all(np.diff(s) >= -1e-12)
    assert s[50] == pytest.approx(0.5)
    assert_allclose(s + s[::-1], 1.0, atol=1e-9)


def test_a_move_takes_its_time_and_is_a_straight_line_in_joint_space():
    clock = Clock()
    arm = make_arm(clock)
    arm.speed_pct = 50
    target = np.array([20.0, -10.0, 90.0, 0.0, 90.0, 0.0])
    duration = arm.move_to(target.tolist(), "test")
    assert duration == pytest.approx(trapezoid_time(20.0, 90.0, 720.0))
    clock.t += duration / 2
    assert arm.moving()
    mid = arm.commanded()
    assert_allclose(mid, (np.array(READY) + target) / 2, atol=1e-9)
    clock.t += duration / 2 + 1e-9
    assert not arm.moving()
    assert_allclose(arm.commanded(), target)


def test_time_scale_shortens_every_motion():
    arm = make_arm(Clock(), time_scale=100.0)
    assert arm.move_joint(1, 50.0) == pytest.approx((50 / 180 + 0.25) / 100)


def test_attained_error_has_the_set_spread_and_offset():
    clock = Clock()
    arm = make_arm(clock, seed=3, repeat_sigma_deg=(0.01,) * 6, systematic_deg=(0.02, 0, 0, 0, 0, 0))
    errors = []
    for _ in range(400):
        clock.t += arm.move_joint(1, 5.0) + 1.0
        clock.t += arm.move_joint(1, -5.0) + 1.0
        errors.append(arm.actual_exact()[0] - arm.commanded()[0])
    e = np.array(errors)
    assert e.mean() == pytest.approx(0.02, abs=0.003)
    assert e.std(ddof=1) == pytest.approx(0.01, rel=0.15)
    assert_allclose(arm.actual_exact()[1:], READY[1:])  # joints that never moved carry no error


def test_backlash_depends_on_the_direction_of_approach():
    clock = Clock()
    arm = make_arm(clock, backlash_deg=(0.0, 0.0, 0.0, 0.0, 0.0, 0.03))
    clock.t += arm.move_joint(6, 10.0) + 1
    assert arm.actual_exact()[5] - arm.commanded()[5] == pytest.approx(0.03)
    clock.t += arm.move_joint(6, -5.0) + 1
    assert arm.actual_exact()[5] - arm.commanded()[5] == pytest.approx(-0.03)


def test_encoders_quantise_the_actual_angle():
    clock = Clock()
    arm = make_arm(clock, systematic_deg=(0.0004, 0, 0, 0, 0, 0))
    clock.t += arm.move_joint(1, 1.0) + 1
    assert arm.pulses(arm.actual_exact())[0] == round(1.0004 * 400000 / 360)
    assert arm.actual()[0] == pytest.approx(round(1.0004 * 400000 / 360) * 360 / 400000)


def test_refusals_use_the_controllers_texts():
    clock = Clock()
    arm = make_arm(clock)
    with pytest.raises(ArmError, match="001 Joint 2 limit exceeded"):
        arm.move_joint(2, 100.0)
    arm.limp.add(3)
    with pytest.raises(ArmError, match="004 Axis 3 is limp"):
        arm.move_joint(3, 1.0)
    arm.set_power(False)
    with pytest.raises(ArmError, match="007 Arm power is OFF"):
        arm.move_joint(1, 1.0)
    arm.set_power(True)
    arm.homed = False
    with pytest.raises(ArmError, match="005 Not homed or not calibrated"):
        arm.move_joint(1, 1.0)
    assert list(arm.motion_log) == []


def test_stop_freezes_the_arm_midway():
    clock = Clock()
    arm = make_arm(clock)
    duration = arm.move_joint(1, 40.0)
    clock.t += duration / 2
    arm.stop()
    assert not arm.moving()
    assert arm.commanded()[0] == pytest.approx(20.0)
    assert arm.motion_log[-1].stopped


def test_power_off_stops_a_motion():
    clock = Clock()
    arm = make_arm(clock)
    arm.move_joint(1, 40.0)
    clock.t += 0.1
    arm.set_power(False)
    assert not arm.moving()


def test_the_shell_reports_the_interpolated_setpoint_while_moving():
    clock = Clock()
    arm = make_arm(clock)
    shell = Shell(arm)
    outcome = shell.execute("joint 1 30")
    assert outcome.is_motion
    clock.t += outcome.motion_s / 2
    w0 = shell.execute("w0").lines
    assert w0[7].split()[1] == "+15.000"
    assert [a for a in shell.execute("armstat").lines if a.startswith(" 1 ")] == [
        " 1        N       N       N       Y"
    ]
    assert shell.execute("joint 1").lines == [
        "Invalid command line arguments.",
        "Usage: joint joint distance",
    ]
    assert shell.execute("").lines == []


def test_the_motion_log_keeps_the_last_entries_only():
    clock = Clock()
    arm = make_arm(clock, log_limit=3)
    for _ in range(5):
        arm.move_joint(1, 1.0)
        clock.t += 10.0
    assert len(arm.motion_log) == 3
    assert [m.end_deg[0] for m in arm.motion_log] == [3.0, 4.0, 5.0]
