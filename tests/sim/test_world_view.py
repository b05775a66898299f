"""The simulated camera gives a frame at every pose, as a real one does: the artifact where its plate is in
view, the background elsewhere; only the measurement refuses a frame without a crossing."""

from __future__ import annotations

import numpy as np
import pytest

from sim.camera import SimCamera
from sim.world import REFERENCE_JOINTS_DEG, World
from station.vision import MeasurementError, measure

#: Poses where the camera sees no artifact: the lift pose (the arm upright), the controller's ready pose,
#: the wrist turned away (the pose the issue's aborted calibration left), the base turned a quarter,
#: the camera looking sideways, and the arm reaching low.
NO_ARTIFACT = {
    "lift": (0.0, 0.0, 0.0, 0.0, 90.0, 0.0),
    "ready": (0.0, 0.0, 90.0, 0.0, 90.0, 0.0),
    "wrist turned": (0.0, 30.0, 60.0, 144.085, 90.0, 0.0),
    "base turned": (90.0, 30.0, 60.0, 0.0, 90.0, 0.0),
    "sideways": (0.0, 30.0, 60.0, 0.0, 0.0, 0.0),
    "low": (0.0, 60.0, 60.0, 0.0, 60.0, 0.0),
}


@pytest.mark.parametrize("joints", NO_ARTIFACT.values(), ids=list(NO_ARTIFACT))
def test_a_pose_that_sees_no_artifact_gives_a_background_frame_the_measurement_refuses(
    joints: tuple[float, ...],
) -> None:
    world = World(joints=lambda: joints)
    camera = SimCamera(world, frame_rate_hz=0)
    with camera:
        frame = camera.grab()
    image = frame.image
    assert image.shape == (480, 640)
    assert image.dtype == np.uint8
    _, truth = world.render(np.random.default_rng(1))
    assert truth is None
    assert world.last_frame_center_mm() is None  # no artifact in the last frame: no truth to compare with
    # the background: its level under the vignetting, nothing else (no edge anywhere)
    assert abs(float(np.median(image)) - world.spec.background_dn) < 3.0
    assert float(np.percentile(image, 99.9) - np.percentile(image, 0.1)) < 20.0
    with pytest.raises(MeasurementError):
        measure(image)


def test_every_pose_within_the_joint_limits_gives_a_frame() -> None:
    world = World()
    rng = np.random.default_rng(19)
    limits = world.kinematics.joint_limits_deg
    for _ in range(40):
        joints = [float(v) for v in rng.uniform(limits[:, 0], limits[:, 1])]
        seen = World(joints=joints.copy)
        image, _ = seen.render(rng)
        assert image.shape == (480, 640)
        assert image.dtype == np.uint8


def test_the_artifact_is_still_rendered_and_measured_where_it_is_in_view() -> None:
    world = World(joints=lambda: REFERENCE_JOINTS_DEG)
    image, truth = world.render(np.random.default_rng(0))
    assert truth is not None
    m = measure(image)
    assert np.hypot(*(np.array(m.center_px) - np.array(truth.center_px))) < 0.05


def test_beyond_the_artifacts_plate_the_camera_sees_the_background() -> None:
    """The table moved 49.5 mm: the plate's edge (50 mm from the crossing) crosses the frame; one groove
    runs up to it, the far side is the background; the crossing is out of view, so no measurement."""
    world = World(joints=lambda: REFERENCE_JOINTS_DEG)
    world.set_table_readings(world.spec.artifact_half_size_mm - 0.5, 0.0)
    image, truth = world.render(np.random.default_rng(0))
    assert truth is not None  # part of the artifact is in view
    side = np.array_split(image, 2, axis=1)
    levels = sorted(float(np.median(half)) for half in side)
    assert abs(levels[0] - world.spec.background_dn) < 5.0  # the background beside the plate
    assert levels[1] > 150.0  # the lands of the plate
    with pytest.raises(MeasurementError):
        measure(image)
