"""Kinematics of the A465: reference poses from the link lengths, IK round trips, limits, tool, WORLD rows."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from station.kinematics import (
    A465_DH,
    DHRow,
    Kinematics,
    KinematicsError,
    UnreachableError,
    pose_from_world_row,
    rot_x,
    rot_y,
    rot_z,
    transform,
    world_row,
)


@pytest.fixture
def kin() -> Kinematics:
    return Kinematics()


def _random_joints(kin: Kinematics, rng: np.random.Generator, n: int, margin: float = 1.0) -> np.ndarray:
    lo = kin.joint_limits_deg[:, 0] + margin
    hi = kin.joint_limits_deg[:, 1] - margin
    return rng.uniform(lo, hi, size=(n, 6))


@pytest.mark.parametrize(
    ("joints", "flange_mm"),
    [
        ((0, 0, 0, 0, 0, 0), (0.0, 0.0, 1041.0)),  # arm straight up: 330 + 305 + 330 + 76
        ((0, 0, 90, 0, 0, 0), (406.0, 0.0, 635.0)),  # forearm horizontal: 330 + 76 forward, 330 + 305 up
    ],
)
def test_forward_reproduces_the_reference_poses_of_the_link_lengths(kin, joints, flange_mm):
    assert_allclose(kin.flange(joints)[:3, 3], flange_mm, rtol=0, atol=1e-9)


def test_all_zero_pose_has_the_flange_axes_of_the_base(kin):
    assert_allclose(kin.flange(np.zeros(6))[:3, :3], np.eye(3), atol=1e-12)


def test_reach_is_the_710_mm_span(kin):
    assert kin.reach_mm == pytest.approx(711.0)


def test_ready_pose_points_the_flange_down(kin):
    T = kin.flange((0, 0, 90, 0, 90, 0))
    assert_allclose(T[:3, 3], (330.0, 0.0, 559.0), atol=1e-9)
    assert_allclose(T[:3, 2], (0.0, 0.0, -1.0), atol=1e-12)


def test_joint_one_turns_the_arm_about_the_vertical(kin):
    p = kin.flange((30, 0, 90, 0, 0, 0))[:3, 3]
    assert_allclose(p, (406 * math.cos(math.radians(30)), 406 * math.sin(math.radians(30)), 635), atol=1e-9)


def test_batch_forward_matches_single_poses(kin):
    q = _random_joints(kin, np.random.default_rng(3), 20)
    batch = kin.flange(q)
    for i in range(len(q)):
        assert_allclose(batch[i], kin.flange(q[i]), atol=1e-12)


def test_inverse_round_trips_forward_for_random_poses(kin):
    rng = np.random.default_rng(7)
    for q in _random_joints(kin, rng, 100):
        T = kin.flange(q)
        solutions = kin.inverse_all(T, tool=False)
        assert any(np.allclose(s, q, atol=1e-7) for s in solutions), q
        for s in solutions:
            assert_allclose(kin.flange(s), T, atol=1e-8)


def test_inverse_picks_the_solution_nearest_the_seed(kin):
    q = np.array([20.0, 10.0, 60.0, 30.0, 40.0, -15.0])
    T = kin.flange(q)
    assert_allclose(kin.inverse(T, seed_deg=q + 2.0, tool=False), q, atol=1e-7)
    assert len(kin.inverse_all(T, tool=False)) > 1  # other branches exist (elbow, wrist flip)


def test_inverse_with_a_tool_solves_for_the_tool_pose():
    tool = transform(rot_x(0.1), (5.0, -3.0, 120.0))
    kin = Kinematics(tool=tool)
    q = np.array([-40.0, 15.0, 70.0, 10.0, 60.0, 25.0])
    T = kin.tool_pose(q)
    assert_allclose(T, kin.flange(q) @ tool, atol=1e-12)
    assert_allclose(kin.inverse(T, seed_deg=q), q, atol=1e-7)


def test_inverse_handles_the_wrist_singularity(kin):
    q = np.array([10.0, 20.0, 50.0, 0.0, 0.0, 30.0])  # joint 5 at 0: joints 4 and 6 share an axis
    T = kin.flange(q)
    s = kin.inverse(T, seed_deg=q, tool=False)
    assert_allclose(kin.flange(s), T, atol=1e-8)


def test_inverse_of_a_calibrated_table_round_trips():
    rng = np.random.default_rng(11)
    perturbed = [
        DHRow(r.alpha_deg + rng.normal(0, 0.05), r.a_mm + rng.normal(0, 0.3), r.d_mm + rng.normal(0, 0.3),
              r.theta_offset_deg + rng.normal(0, 0.05))
        for r in A465_DH
    ]  # fmt: skip
    kin = Kinematics(perturbed)
    for q in _random_joints(kin, rng, 30, margin=5.0):
        T = kin.flange(q)
        assert_allclose(kin.flange(kin.inverse(T, seed_deg=q, tool=False)), T, atol=1e-8)


def test_inverse_rejects_an_unreachable_pose(kin):
    with pytest.raises(UnreachableError):
        kin.inverse(transform(np.eye(3), (2000.0, 0.0, 300.0)), tool=False)


def test_limits_report_each_joint_outside(kin):
    assert kin.within_limits((0, 0, 90, 0, 90, 0))
    assert not kin.within_limits((176, 0, 0, 0, 0, 0))
    assert kin.limit_violations((176, 0, 0, 0, -106, 0)) == [
        (1, 176.0, -175.0, 175.0),
        (5, -106.0, -105.0, 105.0),
    ]
    assert not kin.within_limits((174.5, 0, 0, 0, 0, 0), margin_deg=1.0)


@pytest.mark.parametrize(
    "bad",
    [
        {"dh": A465_DH[:5]},
        {"joint_limits_deg": [(-1, 1)] * 5},
        {"joint_limits_deg": [(1, -1)] * 6},
        {"tool": np.eye(3)},
        {"tool": np.diag([2.0, 1.0, 1.0, 1.0])},
    ],
)
def test_rejects_malformed_models(bad):
    with pytest.raises(KinematicsError):
        Kinematics(**bad)


def test_rejects_joints_of_the_wrong_shape_or_not_finite(kin):
    with pytest.raises(KinematicsError):
        kin.flange((0, 0, 0))
    with pytest.raises(KinematicsError):
        kin.flange((0, 0, float("nan"), 0, 0, 0))


def test_world_row_round_trips_a_pose():
    row = (100.0, -50.0, 400.0, 30.0, -20.0, 170.0)
    assert_allclose(world_row(pose_from_world_row(row)), row, atol=1e-9)


def test_world_row_is_yaw_pitch_roll():
    T = pose_from_world_row((0, 0, 0, 0, 90, 0))
    assert_allclose(T[:3, :3], rot_y(math.pi / 2), atol=1e-12)
    zr, yr, xr = world_row(T)[3:]
    assert yr == pytest.approx(90.0)
    assert_allclose(pose_from_world_row((0, 0, 0, zr, yr, xr)), T, atol=1e-12)


def test_with_tool_keeps_the_arm(kin):
    tool = transform(np.eye(3), (0, 0, 100))
    q = (5, 10, 80, 0, 80, 0)
    assert_allclose(kin.with_tool(tool).tool_pose(q), kin.flange(q) @ tool, atol=1e-12)


def test_jacobian_matches_finite_differences(kin):
    q = np.array([10.0, -20.0, 70.0, 30.0, 50.0, -60.0])
    J = kin.jacobian(q, tool=False)
    h = 1e-6
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = math.degrees(h)
        dp = (kin.flange(q + dq)[:3, 3] - kin.flange(q - dq)[:3, 3]) / (2 * h)
        assert_allclose(J[:3, i], dp, atol=1e-5)


def _link_product(dh, q_deg):
    """Reference: the link transforms multiplied one by one, Hayati's beta included."""
    T = np.eye(4)
    for row, q in zip(dh, q_deg, strict=True):
        theta = math.radians(q + row.theta_offset_deg)
        T = (
            T
            @ transform(rot_x(math.radians(row.alpha_deg)), (0, 0, 0))
            @ transform(np.eye(3), (row.a_mm, 0, 0))
            @ transform(rot_y(math.radians(row.beta_deg)), (0, 0, 0))
            @ transform(rot_z(theta), (0, 0, 0))
            @ transform(np.eye(3), (0, 0, row.d_mm))
        )
    return T


@pytest.mark.parametrize("beta", [0.0, 0.05, -1.0])
def test_hayati_beta_tilts_the_link_about_y(beta):
    dh = list(A465_DH)
    dh[2] = DHRow(dh[2].alpha_deg, dh[2].a_mm + 0.3, dh[2].d_mm, dh[2].theta_offset_deg, beta_deg=beta)
    q = (10.0, 25.0, 70.0, -30.0, 60.0, 15.0)
    assert_allclose(Kinematics(dh).flange(q), _link_product(dh, q), atol=1e-9)


def test_inverse_reaches_a_pose_with_a_tilted_link():
    dh = list(A465_DH)
    dh[2] = DHRow(0.0, 305.2, 0.1, -90.02, beta_deg=0.05)
    kin = Kinematics(dh)
    q = np.array([10.0, 25.0, 70.0, -30.0, 60.0, 15.0])
    q_back = kin.inverse(kin.flange(q), seed_deg=q, tool=False)
    assert_allclose(q_back, q, atol=1e-7)
