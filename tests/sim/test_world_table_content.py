"""What lies on the simulated X-Y table, swapped at run time (``World.place_on_table``): the render, the
distance sensor's surface and the table's frame follow, as they would for a person changing it (issue 23).
"""

from __future__ import annotations

import numpy as np
import pytest

from sim._world_target import target_frame
from sim.world import World, WorldSpec
from station.camcal import detect_target


def test_the_world_starts_with_its_spec_content_and_swaps_it() -> None:
    assert World(WorldSpec()).table_content == "cross"
    assert World(WorldSpec(table_artifact="ruler")).table_content == "ruler"
    assert World(WorldSpec(calibration_target=True)).table_content == "target"
    with pytest.raises(ValueError, match="one of cross, ruler, target"):
        World(WorldSpec()).place_on_table("plate")  # type: ignore[arg-type]


def test_the_render_follows_what_is_put_on_the_table() -> None:
    world = World(WorldSpec())
    rng = np.random.default_rng(2)
    _, crossing = world.render(rng)
    assert crossing is not None
    assert world.last_target is None
    world.place_on_table("target")
    image, crossing = world.render(rng)
    assert crossing is None
    assert world.last_target is not None
    assert detect_target(image).count >= 60
    world.place_on_table("ruler")
    cam = world.camera_pose()
    assert world.seen_ruler(cam) == len(world.ruler_poses()) - 1  # the table's ruler, last
    _, crossing = world.render(rng)
    assert crossing is None
    assert world.last_target is None
    assert world.last_frame_ruler() is not None
    world.place_on_table("cross")
    assert world.seen_ruler(cam) is None
    _, crossing = world.render(rng)
    assert crossing is not None
    assert world.last_frame_ruler() is None


def test_the_new_content_lies_where_the_carriage_is_and_the_sensor_reads_it() -> None:
    world = World(WorldSpec())
    world.set_table_readings(2.0, -1.5)
    world.place_on_table("ruler")
    table = world.table_artifact_pose()
    ruler = world.ruler_poses()[-1]
    np.testing.assert_allclose(ruler[:3, :3], table[:3, :3])
    # the ruler's frame moved with the carriage: its 125 mm mark lies where the crossing would
    np.testing.assert_allclose(ruler[:3, 3] + 125.0 * ruler[:3, 0], table[:3, 3], atol=1e-9)
    head = world.camera_pose()
    surface = world.surface_pose(head)
    hit = ruler[:3, :3].T @ (surface[:3, 3] - ruler[:3, 3])  # on the ruler's glass, in its plane
    assert abs(hit[2]) < 1e-9
    assert 0.0 < hit[0] < 250.0
    world.place_on_table("target")
    _, _ = world.render(np.random.default_rng(3))
    truth = world.last_target
    assert truth is not None
    seen = np.eye(4)
    seen[:3, :3], seen[:3, 3] = truth.pose.rotation, truth.pose.translation_mm
    # the target lies on the carriage where it is now, in the table artifact's place
    np.testing.assert_allclose(head @ seen, target_frame(world.table_artifact_pose()), atol=1e-6)
    np.testing.assert_allclose(world.surface_pose(head), world.table_artifact_pose())


def test_a_seeded_lens_is_one_lens_for_the_target_and_the_cross() -> None:
    """The calibration target is seen through the seeded true intrinsics; the cross, at the same focal
    length's scale: a camera model calibrated on the target agrees with the grooves' scale."""
    world = World(WorldSpec(true_intrinsics_seed=3))
    K = world.true_intrinsics.camera_matrix
    focal = float(K[0, 0] + K[1, 1]) / 2.0
    assert abs(focal / world.spec.camera.focal_px - 1.0) > 0.005  # the seed's focal is not the nominal
    assert world.true_camera.px_per_mm * world.spec.camera.working_distance_mm == pytest.approx(focal)
    # an explicit magnification seed still decides the artifact's scale
    both = World(WorldSpec(true_intrinsics_seed=3, magnification_seed=1))
    assert both.magnification_error == pytest.approx(
        World(WorldSpec(magnification_seed=1)).magnification_error
    )
