"""The camera-calibration target on the simulated table (``WorldSpec.calibration_target``), seen through
the camera's seeded true intrinsics (``WorldSpec.true_intrinsics_seed``): what a camera-calibration
session on the sim station will see (issue 23, item 2)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.lens import nominal_intrinsics, true_intrinsics
from sim.world import World, WorldSpec
from station.camcal import detect_target


def test_the_table_carries_the_target_seen_through_the_true_intrinsics() -> None:
    world = World(WorldSpec(calibration_target=True, true_intrinsics_seed=3))
    truth_camera = true_intrinsics(3)
    np.testing.assert_array_equal(world.true_intrinsics.camera_matrix, truth_camera.camera_matrix)
    assert world.true_intrinsics.fx != pytest.approx(nominal_intrinsics().fx, rel=1e-4)  # not the nominal
    image, crossing = world.render(np.random.default_rng(1))
    assert crossing is None  # no groove crossing in this frame
    truth = world.last_target
    assert truth is not None
    # at the reference pose the camera is square to the target, its centre in focus on the optical axis
    assert truth.pose.rotation[2, 2] > np.cos(np.radians(1.0))
    assert abs(float(np.median(truth.depth_mm)) - world.spec.camera.working_distance_mm) < 0.1
    found = detect_target(image)
    assert found.count >= 60
    err = found.corners_px - truth.corners_px[found.ids]
    assert float(np.sqrt(np.mean(err**2))) < 0.05  # px: the corners are where the true camera puts them


def test_without_the_option_the_table_carries_the_artifact() -> None:
    world = World(WorldSpec())
    _, crossing = world.render(np.random.default_rng(1))
    assert crossing is not None
    assert world.last_target is None
    np.testing.assert_allclose(world.true_intrinsics.camera_matrix, nominal_intrinsics().camera_matrix)
