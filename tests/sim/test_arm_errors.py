"""The sim arm's error model: Table 2 reproduced, determinism, a perfect arm, and each component's effect."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sim.arm_errors import (
    DEFAULT_ARM_ERRORS,
    SEED_SEQUENCES_MM,
    SEED_TABLE2_MM,
    ArmErrorModel,
    FlangeErrors,
    FlangeErrorSequence,
    JointErrors,
)
from sim.controller import ControllerTwin, TwinSettings
from sim.repeatability_truth import ProtocolSettings, away_signs, simulate_repeatability, true_centers_mm
from sim.world import World, WorldSpec
from station.kinematics import A465_DH
from station.vision import measure

REF = WorldSpec().reference_joints_deg
ZERO6 = (0.0,) * 6
# RP / sigma of N(0, sigma) in one direction (E|x| + 3 SD|x|) and of an isotropic 2-D normal (Rayleigh)
RP_PER_SIGMA_1D = math.sqrt(2 / math.pi) + 3 * math.sqrt(1 - 2 / math.pi)
RP_PER_SIGMA_2D = math.sqrt(math.pi / 2) + 3 * math.sqrt(2 - math.pi / 2)


def only(
    *,
    sigma: tuple[float, ...] = ZERO6,
    backlash: tuple[float, ...] = ZERO6,
    settle: tuple[float, ...] = ZERO6,
    flange: FlangeErrors | None = None,
) -> ArmErrorModel:
    joints = JointErrors(sigma_deg=sigma, backlash_deg=backlash, settle_deg=settle)  # type: ignore[arg-type]
    return ArmErrorModel(joints, flange or FlangeErrors.none())


def sensitivity_mm_per_deg(joint: int) -> float:
    """How far the true centre moves per degree of ``joint`` at the reference pose (perfect world)."""
    world = World(replace(WorldSpec(), flange_errors=FlangeErrors.none()))
    q = np.array(REF)
    q[joint - 1] += 1e-4
    before, after = world.center_mm_at(REF, tool_point=True), world.center_mm_at(tuple(q), tool_point=True)
    return float(np.hypot(*np.subtract(after, before))) / 1e-4


# --------------------------------------------------------------------------- Table 2


def test_the_default_model_reproduces_the_seeds_table_2_for_seed_0() -> None:
    rp = simulate_repeatability(seed=0).rp_mm
    for joint, seed_mm in SEED_TABLE2_MM.items():
        assert rp[joint] == pytest.approx(seed_mm, rel=0.30), joint
    low, high = min(SEED_SEQUENCES_MM.values()), max(SEED_SEQUENCES_MM.values())
    for name in SEED_SEQUENCES_MM:
        assert 0.75 * low <= rp[name] <= 1.25 * high, name


def test_the_twin_and_the_world_take_the_default_model() -> None:
    settings = TwinSettings()
    joints = DEFAULT_ARM_ERRORS.joints
    assert settings.repeat_sigma_deg == joints.sigma_deg
    assert settings.backlash_deg == joints.backlash_deg
    assert settings.settle_deg == joints.settle_deg
    assert settings.settle_time_s == joints.settle_time_s
    assert WorldSpec().flange_errors == DEFAULT_ARM_ERRORS.flange


def test_the_protocol_moves_joints_2_and_3_negative_away_from_the_artifact() -> None:
    assert away_signs(World()) == (1, -1, -1, 1, 1, 1)


def test_a_session_is_deterministic_per_seed() -> None:
    protocol = ProtocolSettings(cycles=5, warmup_cycles=1, joints=(1, 5))
    a = simulate_repeatability(seed=3, protocol=protocol)
    b = simulate_repeatability(seed=3, protocol=protocol)
    c = simulate_repeatability(seed=4, protocol=protocol)
    for name in a.points_mm:
        assert_allclose(a.points_mm[name], b.points_mm[name], rtol=0, atol=0)
        assert not np.allclose(a.points_mm[name], c.points_mm[name], rtol=0, atol=1e-6)


def test_a_perfect_arm_returns_exactly() -> None:
    run = simulate_repeatability(ArmErrorModel.none(), seed=0, protocol=ProtocolSettings(cycles=5))
    for name, rp in run.rp_mm.items():
        assert rp < 1e-9, name
    assert_allclose(run.points_mm["S1"], run.points_mm["J1"], atol=1e-9)  # the same reference every time


# ------------------------------------------------------------------- each component, as the camera sees it


def test_joint_noise_shows_as_its_sigma_through_the_kinematics() -> None:
    sigma = 0.002
    protocol = ProtocolSettings(cycles=400, warmup_cycles=0, joints=(1,), sequences=False)
    rp = simulate_repeatability(only(sigma=(sigma, 0, 0, 0, 0, 0)), seed=1, protocol=protocol).rp_mm["J1"]
    expected = RP_PER_SIGMA_1D * sigma * sensitivity_mm_per_deg(1)
    assert rp == pytest.approx(expected, rel=0.10)
    assert rp > 0.03  # 0.002 deg at the camera's 0.48 m from joint 1's axis: ~17 um per sigma


def test_backlash_is_constant_under_the_protocol_and_shows_between_approach_directions() -> None:
    backlash = 0.01
    model = only(backlash=(backlash, 0, 0, 0, 0, 0))
    protocol = ProtocolSettings(cycles=10, joints=(1,), sequences=False)
    assert simulate_repeatability(model, protocol=protocol).rp_mm["J1"] < 1e-9  # same side every cycle

    clock = [0.0]
    twin = ControllerTwin(
        TwinSettings(**model.joints.twin_options(), start_pose_deg=REF, time_scale=1.0),
        clock=lambda: clock[0],
    )
    try:
        world = World(replace(WorldSpec(), flange_errors=FlangeErrors.none()), joints=twin.arm.actual_exact)
        clock[0] += twin.arm.move_joint(1, 5.0) + 1.0
        clock[0] += twin.arm.move_joint(1, -5.0) + 1.0  # back from above: -backlash
        from_above = np.array(world.center_mm(tool_point=True))
        clock[0] += twin.arm.move_joint(1, -5.0) + 1.0
        clock[0] += twin.arm.move_joint(1, 5.0) + 1.0  # back from below: +backlash
        from_below = np.array(world.center_mm(tool_point=True))
    finally:
        twin.close()
    gap = float(np.hypot(*(from_below - from_above)))
    assert gap == pytest.approx(2 * backlash * sensitivity_mm_per_deg(1), rel=0.01)


def test_servo_settling_decays_with_the_time_waited_after_arrival() -> None:
    model = only(settle=(0.004, 0, 0, 0, 0, 0))
    tau = model.joints.settle_time_s
    run = {
        settle: simulate_repeatability(
            model, seed=2, protocol=ProtocolSettings(cycles=30, joints=(1,), sequences=False, settle_s=settle)
        ).rp_mm["J1"]
        for settle in (0.0, 2 * tau, 5 * tau)
    }
    expected_at_arrival = RP_PER_SIGMA_1D * 0.004 * sensitivity_mm_per_deg(1)
    assert run[0.0] == pytest.approx(expected_at_arrival, rel=0.35)  # one 30-cycle sample
    # the same draws, waited longer: the residual has decayed by exp(-t / tau)
    assert run[2 * tau] / run[0.0] == pytest.approx(math.exp(-2), rel=1e-3)
    assert run[5 * tau] / run[0.0] == pytest.approx(math.exp(-5), rel=1e-3)


def test_the_cartesian_floor_shows_even_for_joint_6_which_turns_about_the_optical_axis() -> None:
    sigma_mm = 0.004
    protocol = ProtocolSettings(cycles=400, warmup_cycles=0, joints=(6,), sequences=False)
    model = only(flange=FlangeErrors(sigma_mm=sigma_mm, drift_sigma_mm=0.0, thermal_mm=0.0))
    rp = simulate_repeatability(model, seed=5, protocol=protocol).rp_mm["J6"]
    assert rp == pytest.approx(RP_PER_SIGMA_2D * sigma_mm, rel=0.10)  # base x, y lie in the image plane


def test_the_flange_error_moves_the_seen_crossing_by_minus_the_camera_shift() -> None:
    spec = WorldSpec(
        flange_errors=FlangeErrors(sigma_mm=0.005, drift_sigma_mm=0.002, thermal_mm=0.01),
        true_dh=A465_DH,  # a perfect arm: the camera square to the artifact, as the first-order law assumes
    )
    moves = [0]
    world = World(spec, moves=lambda: moves[0], seed=7)
    nominal = np.array(world.center_mm_at(REF))
    R_art = world.artifact_pose()[:3, :3]
    for k in (0, 1, 17, 300):
        moves[0] = k
        e = R_art.T @ world.flange_errors.at(
            k
        )  # the camera's shift in the artifact's axes (n: into the table)
        # +e in the plane moves the crossing seen by -e; toward the table (+n) the image origin's ray, 4 mm
        # off the optical axis, meets the plane nearer the axis: centre_mm shrinks by e_n / working distance
        expected = nominal - e[:2] - nominal * e[2] / spec.camera.working_distance_mm
        assert_allclose(world.center_mm(), expected, atol=1e-8)
        assert (np.linalg.norm(e) > 0.0) == (k > 0)  # none before the first motion: the set-up pose


def test_thermal_warm_up_and_drift_follow_their_laws() -> None:
    thermal = FlangeErrorSequence(FlangeErrors(sigma_mm=0.0, drift_sigma_mm=0.0, thermal_mm=0.01), seed=1)
    for k in (0, 50, 400, 4000):
        assert np.linalg.norm(thermal.at(k)) == pytest.approx(0.01 * (1 - math.exp(-k / 400.0)), abs=1e-12)
    drift = FlangeErrorSequence(
        FlangeErrors(sigma_mm=0.0, drift_sigma_mm=0.003, drift_moves=20.0, thermal_mm=0.0), seed=2
    )
    x = np.array([drift.at(k) for k in range(6000)])
    assert x.std() == pytest.approx(0.003, rel=0.15)  # bounded: a stationary wander, not a random walk
    lag1 = np.mean([np.corrcoef(x[:-1, i], x[1:, i])[0, 1] for i in range(3)])
    assert lag1 == pytest.approx(math.exp(-1 / 20.0), abs=0.03)
    assert_allclose(drift.at(123), FlangeErrorSequence(drift.errors, seed=2).at(123))  # any order, same value


# --------------------------------------------------------------------------- truth for the station's tests


def test_the_truth_is_what_the_station_measures_in_the_frame() -> None:
    q = list(REF)
    world = World(WorldSpec(), joints=lambda: q)
    assert world.moves() == 0
    q[0] += 0.01
    image, _ = world.render(np.random.default_rng(0))
    truth = world.last_frame_center_mm()
    assert truth is not None
    assert_allclose(measure(image).center_mm, truth, atol=0.001)  # per-image scale: well under 1 um
    assert world.moves() == 1  # a new joint reading counts as a motion when no counter is given


def test_the_world_follows_the_twins_motion_counter_and_true_centres_replay_captures() -> None:
    clock = [0.0]
    twin = ControllerTwin(TwinSettings(start_pose_deg=REF, seed=1), clock=lambda: clock[0])
    try:
        world = World(WorldSpec(), joints=twin.arm.actual_exact, seed=1)
        joints, moves, seen = [], [], []
        for _ in range(3):
            clock[0] += twin.arm.move_joint(5, 10.0) + 1.0
            clock[0] += twin.arm.move_joint(5, -10.0) + 1.0
            assert world.moves() == twin.arm.moves
            joints.append(twin.arm.actual_exact().tolist())
            moves.append(twin.arm.moves)
            seen.append(world.center_mm(tool_point=True))
    finally:
        twin.close()
    assert_allclose(true_centers_mm(world, joints, moves), seen, atol=1e-12)
    without_floor = true_centers_mm(world, joints)
    assert np.all(np.hypot(*(without_floor - np.array(seen)).T) > 0.0)


def test_bad_parameters_are_refused_with_the_name() -> None:
    with pytest.raises(ValueError, match="sigma_deg"):
        JointErrors(sigma_deg=(-0.001, 0, 0, 0, 0, 0))
    with pytest.raises(ValueError, match="settle_time_s"):
        JointErrors(settle_time_s=0.0)
    with pytest.raises(ValueError, match="sigma_mm"):
        FlangeErrors(sigma_mm=math.nan)
    with pytest.raises(ValueError, match="drift_moves"):
        FlangeErrors(drift_moves=0.0)
    with pytest.raises(ValueError, match="move"):
        FlangeErrorSequence(FlangeErrors()).at(-1)
    with pytest.raises(ValueError, match="cycles"):
        ProtocolSettings(cycles=1)
