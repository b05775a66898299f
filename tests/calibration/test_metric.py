"""The relative error: zero for the true model on exact data, the in-plane distance of a known offset."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sim import calibration_sessions as synthetic
from station.calibration import CalibrationError, crossing_positions, pair_errors_um, relative_error_um


@pytest.fixture(scope="module")
def level():
    """A true arm with level artifacts (the metric's approximation is then exact) and exact captures."""
    truth = synthetic.make_truth(5)
    truth.normals = {k: np.array([0.0, 0.0, 1.0]) for k in truth.normals}
    obs = synthetic.session(truth, seed=6, noise_mm=0.0, placements=(0, 1), inview=0)
    return truth, obs


def test_true_model_on_exact_square_captures_gives_zero(level):
    truth, obs = level
    positions = crossing_positions(obs, truth.kinematics, synthetic.CAMERA, synthetic.MOUNT)
    for o, p in zip(obs, positions, strict=True):
        assert np.linalg.norm(p - truth.points[o.placement]) < 1e-6
    assert relative_error_um(obs, truth.kinematics, synthetic.CAMERA, synthetic.MOUNT) < 1e-3


def test_a_known_offset_in_the_image_is_its_distance_in_the_plane(level):
    truth, obs = level
    two = [o for o in obs if o.placement == 0][:2]
    moved = [two[0], replace(two[1], center_px=(two[1].center_px[0] + 100.0, two[1].center_px[1]))]
    errors = pair_errors_um(moved, truth.kinematics, synthetic.CAMERA, synthetic.MOUNT)
    assert errors.shape == (1,)
    assert errors[0] == pytest.approx(1000.0, rel=0.01)  # 100 px at 10 um per px at the focal plane


def test_pairs_only_join_different_configurations_of_one_placement(level):
    truth, obs = level
    errors = pair_errors_um(obs, truth.kinematics, synthetic.CAMERA, synthetic.MOUNT)
    per_placement = [sum(1 for o in obs if o.placement == k) for k in (0, 1)]
    assert errors.size == sum(n * (n - 1) // 2 for n in per_placement)


def test_needs_two_configurations(level):
    truth, obs = level
    with pytest.raises(CalibrationError, match="at least two configurations"):
        relative_error_um(obs[:1], truth.kinematics, synthetic.CAMERA, synthetic.MOUNT)
