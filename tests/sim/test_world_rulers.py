"""The simulated cell's rulers and its camera's true magnification (issue 22): the world renders a ruler
where the camera looks at one, through the same camera model and presets as the crossings, with truth;
its magnification differs from the nominal when the spec's seed says so; its sensor reads the glass."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim._render_camera import F4_DEFOCUS_PX_PER_MM
from sim.cell_rulers import DEFAULT_RULERS, ray_hit
from sim.distance_sensor import DistanceSensorTwin, HeadModel, world_source
from sim.station import SIM_SENSOR_MOUNT
from sim.world import REFERENCE_JOINTS_DEG, World, WorldSpec, magnification_error
from station.kinematics import rot_z, transform
from station.vision import RulerParams, measure_ruler

WD = 68.0


def _looking_at(
    world: World, ruler: int, s_mm: float, *, turn_deg: float = 0.0, depth_mm: float = WD
) -> list[float]:
    """Joints (true arm) that put the camera square over ``ruler`` at ``s_mm``, turned and at a depth."""
    F = world.ruler_poses()[ruler]
    R = F[:3, :3] @ rot_z(math.radians(turn_deg))
    target = transform(R, F[:3, :3] @ np.array([s_mm, 0.1, 0.0]) + F[:3, 3] - depth_mm * R[:, 2])
    return [float(v) for v in world.kinematics.inverse_all(target)[0]]


def _params(world: World) -> RulerParams:
    return RulerParams(camera_matrix=world.spec.camera.matrix().tolist(), dist_coeffs=[0.0] * 5)


def test_the_cell_has_rulers_in_two_directions_on_the_table_and_one_on_an_angle_block() -> None:
    world = World()
    frames = world.ruler_poses()
    assert len(frames) == len(DEFAULT_RULERS) == 3
    table_z = world.table_artifact_pose()[2, 3]
    level = [F for F in frames if abs(F[2, 2]) > 0.999999]
    assert len(level) == 2
    assert all(abs(F[2, 3] - table_z) < 1e-9 for F in level)
    assert abs(level[0][:3, 0] @ level[1][:3, 0]) < 1e-9  # two directions, square to each other
    block = [F for F in frames if abs(F[2, 2]) <= 0.999999]
    assert len(block) == 1
    assert math.degrees(math.acos(-block[0][2, 2])) == pytest.approx(25.0)
    # none in view from the reference pose, where the table's crossing is
    assert world.seen_ruler(world.camera_pose_at(REFERENCE_JOINTS_DEG)) is None


@pytest.mark.parametrize("ruler", range(3))
def test_a_camera_over_a_ruler_sees_it_and_its_truth_is_where_the_optical_axis_meets_it(ruler: int) -> None:
    q = [0.0] * 6
    world = World(joints=lambda: q)
    q[:] = _looking_at(world, ruler, 120.0, turn_deg=15.0)
    image, cross = world.render(np.random.default_rng(ruler))
    assert cross is None  # no crossing in this frame
    seen = world.last_frame_ruler()
    assert seen is not None
    index, truth = seen
    assert index == ruler
    camera = world.camera_pose()
    hit = ray_hit(camera[:3, 3], camera[:3, 2], world.ruler_poses()[ruler])
    assert hit is not None
    assert truth.principal_position_mm == pytest.approx(hit[0], abs=1e-9)
    assert truth.principal_offset_mm == pytest.approx(hit[1], abs=1e-9)
    m = measure_ruler(image, _params(world))
    assert abs(m.position_mm - truth.principal_position_mm) < 5e-5  # 50 nm: the nominal preset
    assert abs(m.offset_mm - truth.principal_offset_mm) < 2e-3


def test_the_default_camera_is_exact_and_a_seeded_one_is_not() -> None:
    assert World().magnification_error == 0.0
    assert World().true_camera == WorldSpec().camera
    errors = [magnification_error(seed) for seed in range(50)]
    assert all(abs(e) <= 0.02 for e in errors)
    assert max(errors) > 0.01
    assert min(errors) < -0.01
    world = World(WorldSpec(magnification_seed=7))
    assert world.magnification_error == magnification_error(7) != 0.0
    assert world.true_camera.px_per_mm == pytest.approx(100.0 * (1.0 + magnification_error(7)))
    assert world.spec.camera.px_per_mm == 100.0  # what the station is told


def test_a_station_trusting_the_nominal_scale_is_wrong_by_the_true_magnification() -> None:
    q = [0.0] * 6
    world = World(WorldSpec(magnification_seed=7), joints=lambda: q)
    e = world.magnification_error
    q[:] = _looking_at(world, 0, 100.0)
    image, _ = world.render(np.random.default_rng(3))
    m = measure_ruler(image, _params(world))
    # the ruler's pitch measures the true scale...
    assert m.extra["px_per_mm"] / world.spec.camera.px_per_mm - 1.0 == pytest.approx(e, abs=2e-5)
    # ...and a length read in the image with the nominal scale is off by it: the origin pixel's distance
    # along the ruler from the principal point
    cx, cy = world.spec.camera.principal_point
    s0, _ = m.to_ruler_mm(0.0, 0.0)
    direction = np.array([math.cos(math.radians(m.angle_deg)), math.sin(math.radians(m.angle_deg))])
    nominal_mm = float(-np.array([cx, cy]) @ direction) / world.spec.camera.px_per_mm
    assert (s0 - m.position_mm) / nominal_mm - 1.0 == pytest.approx(-e / (1 + e), abs=1e-4)
    assert abs(e) > 0.005


def test_frames_off_the_focal_plane_are_measured_with_the_f4_lens() -> None:
    # 1.5 mm off focus: 4.7 px of defocus at f/4 (the world's old 20 px/mm, 30 px, hid every graduation)
    assert WorldSpec().defocus_px_per_mm == F4_DEFOCUS_PX_PER_MM
    q = [0.0] * 6
    world = World(joints=lambda: q)
    for dz in (-1.5, 1.5):
        q[:] = _looking_at(world, 1, 60.0, depth_mm=WD + dz)
        image, _ = world.render(np.random.default_rng(5))
        _, truth = world.last_frame_ruler() or (None, None)
        assert truth is not None
        m = measure_ruler(image, _params(world))
        assert abs(m.position_mm - truth.principal_position_mm) < 2e-4
        assert truth.px_per_mm == pytest.approx(world.spec.camera.focal_px / (WD + dz), rel=1e-3)
        assert m.extra["px_per_mm"] == pytest.approx(truth.px_per_mm, rel=2e-5)  # the scale at that depth


def test_the_sensor_reads_the_ruler_glass_where_its_beam_falls_on_it() -> None:
    q = [0.0] * 6
    world = World(joints=lambda: q)
    twin = DistanceSensorTwin(world_source(world, SIM_SENSOR_MOUNT.matrix()), HeadModel(), seed=0)
    q[:] = _looking_at(world, 0, 100.0, turn_deg=0.0)  # the beam, 30 mm along the image's x, along the ruler
    hit = twin.truth()
    assert hit.distance_mm == pytest.approx(WD, abs=1e-6)
    assert twin.readout().kind == "value"
    q[:] = _looking_at(world, 0, 100.0, turn_deg=90.0)  # the beam 30 mm across: beside the 30 mm glass
    assert twin.readout().kind == "invalid"
