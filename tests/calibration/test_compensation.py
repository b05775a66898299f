"""Compensated moves: IK with the calibrated model, joint moves split within the driver's step."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from station.calibration import CalibrationError, compensated_joints, compensated_steps, joint_steps
from station.kinematics import rot_z, transform


def test_compensated_joints_reach_the_requested_pose_under_the_calibrated_model(fitted):
    calibrated = fitted.result.kinematics()
    current = np.array(fitted.observations[0].joints_deg)
    here = calibrated.tool_pose(current)
    target = here @ transform(rot_z(np.radians(5.0)), (1.5, -2.0, 0.3))  # a small move in the camera frame
    q = compensated_joints(calibrated, target, current_deg=current)
    reached = calibrated.tool_pose(q)
    assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-6
    assert_allclose(reached[:3, :3], target[:3, :3], atol=1e-9)
    assert np.max(np.abs(q - current)) < 10.0  # the same shoulder, elbow and wrist
    # the nominal controller, sent these joints, would be elsewhere: compensation matters
    nominal = fitted.result.nominal_kinematics().tool_pose(q)
    assert np.linalg.norm(nominal[:3, 3] - target[:3, 3]) > 0.05


def test_joint_steps_stay_within_the_largest_step_and_end_exactly():
    start = np.array([0.0, 30.0, 60.0, 0.0, 90.0, 0.0])
    end = np.array([25.0, 10.0, 61.0, -40.0, 80.0, 3.0])
    steps = joint_steps(start, end, max_step_deg=10.0)
    assert len(steps) == 4
    previous = start
    for s in steps:
        assert np.max(np.abs(s - previous)) <= 10.0 + 1e-12
        previous = s
    assert np.array_equal(steps[-1], end)
    assert len(joint_steps(start, start + 0.5, max_step_deg=10.0)) == 1


def test_joint_steps_rejects_a_bad_step():
    with pytest.raises(CalibrationError, match="max_step_deg"):
        joint_steps(np.zeros(6), np.ones(6), max_step_deg=0.0)


def test_compensated_steps_end_at_the_compensated_joints_within_the_step(fitted):
    calibrated = fitted.result.kinematics()
    current = np.array(fitted.observations[0].joints_deg)
    target = calibrated.tool_pose(current) @ transform(rot_z(np.radians(-20.0)), (0.0, 0.0, 0.0))
    steps = compensated_steps(calibrated, target, current_deg=current, max_step_deg=5.0)
    assert len(steps) >= 4  # joint 6 turns about 20 deg
    assert_allclose(steps[-1], compensated_joints(calibrated, target, current_deg=current))
    assert np.max(np.abs(np.diff(np.vstack([current, *steps]), axis=0))) <= 5.0 + 1e-9
