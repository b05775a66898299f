"""The direction check's maths: what a small camera move does to the view, through the nominal model."""

from __future__ import annotations

import numpy as np
import pytest

from station.camera_model import CameraIntrinsics
from station.kinematics import rot_z, transform
from station.selftest import agreement, predicted_signal, signal, wrap_cross_deg

F = 6800.0  # px: 68 mm working distance over 0.01 mm pixels
INTRINSICS = CameraIntrinsics(
    np.array([[F, 0.0, 319.5], [0.0, F, 239.5], [0.0, 0.0, 1.0]]), np.zeros(5), (640, 480)
)
LOOKING_DOWN = transform(np.diag([-1.0, 1.0, -1.0]), (400.0, 0.0, 300.0))


def test_a_camera_moved_along_its_x_sees_the_crossing_move_the_other_way() -> None:
    after = LOOKING_DOWN @ transform(np.eye(3), (1.0, 0.0, 0.0))
    s = predicted_signal(LOOKING_DOWN, after, (319.5, 239.5), 0.0, INTRINSICS, 68.0)
    np.testing.assert_allclose(s, [-100.0, 0.0, 0.0, 0.0], atol=1e-6)


def test_a_turn_about_the_optical_axis_and_a_move_toward_the_crossing() -> None:
    turned = LOOKING_DOWN @ transform(rot_z(np.radians(2.0)), (0.0, 0.0, 0.0))
    s = predicted_signal(LOOKING_DOWN, turned, (319.5, 239.5), 0.0, INTRINSICS, 68.0)
    # the camera turns +2 deg about its z: the scene turns -2 deg in the image, 1000 px per rad
    np.testing.assert_allclose(s, [0.0, 0.0, -1000.0 * np.radians(2.0), 0.0], atol=1e-6)
    closer = LOOKING_DOWN @ transform(np.eye(3), (0.0, 0.0, 0.68))
    s = predicted_signal(LOOKING_DOWN, closer, (319.5, 239.5), 0.0, INTRINSICS, 68.0)
    assert s[3] == pytest.approx(1000.0 * (68.0 / 67.32 - 1.0), rel=1e-9)  # 1 % closer: ~1 % larger


def test_agreement_and_the_cross_s_ninety_degree_symmetry() -> None:
    p = signal(10.0, 0.0, 0.0, 0.0)
    assert agreement(p, signal(11.0, 0.0, 0.0, 0.0)) == pytest.approx((1.0, 1.1))
    assert agreement(p, signal(-10.0, 0.0, 0.0, 0.0))[0] == pytest.approx(-1.0)
    assert wrap_cross_deg(89.0) == pytest.approx(-1.0)
    assert wrap_cross_deg(-46.0) == pytest.approx(44.0)
    with pytest.raises(ValueError, match="changes nothing"):
        agreement(np.zeros(4), p)
