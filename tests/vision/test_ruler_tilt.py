"""A ruler seen leaning: the offset across it is read on the ruler's plane, foreshortening included."""

from __future__ import annotations

import numpy as np
import pytest

from sim._render_camera import CameraSpec, Pose
from sim.ruler import render_ruler
from station.vision import RulerParams, measure_ruler

CAMERA = CameraSpec()


@pytest.mark.parametrize(("tilt_x", "tilt_y"), [(15.0, 0.0), (-12.0, 6.0)])
def test_a_leaning_view_reads_the_offset_on_the_plane(tilt_x: float, tilt_y: float) -> None:
    # the ruler along the image's x, leaning about its own axis: the image foreshortens t by cos(tilt)
    # (3.4 % at 15 deg); the principal point 0.6 mm off the ruler's axis
    pose = Pose(0.3, -0.6, rotation_deg=4.0, tilt_x_deg=tilt_x, tilt_y_deg=tilt_y)
    image, truth = render_ruler(pose, anchor_mm=80.0, camera=CAMERA, rng=np.random.default_rng(3))
    params = RulerParams(camera_matrix=CAMERA.matrix().tolist(), dist_coeffs=[0.0] * 5, max_tilt_deg=20.0)
    m = measure_ruler(image, params)
    assert abs(truth.principal_offset_mm) > 0.5
    assert m.offset_mm == pytest.approx(truth.principal_offset_mm, abs=1e-3)  # 1 um (was 20 um off)
    assert m.position_mm == pytest.approx(truth.principal_position_mm, abs=1e-4)
    assert m.extra["tips"]["width_ratio"] == pytest.approx(1.0, abs=1e-3)
