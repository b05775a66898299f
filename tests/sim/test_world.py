"""The simulated world: table moves, joint moves and the camera agree with the geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.arm_errors import FlangeErrors
from sim.camera import SimCamera
from sim.operator import SimOperator
from sim.world import TableImperfections, World, WorldSpec, euler_xyz
from station.devices import Camera, DeviceConnectionError, InvalidSettingError, Roi
from station.kinematics import rot_x, rot_y, rot_z
from station.prompts import PromptBroker, PromptField
from station.vision import measure

PERFECT = WorldSpec(
    table=TableImperfections(skew_deg=0.0, resolution_in=0.0, backlash_mm=0.0),
    flange_errors=FlangeErrors.none(),
)


def centre(world: World, seed: int = 0) -> np.ndarray:
    image, _ = world.render(np.random.default_rng(seed))
    return np.array(measure(image).center_px)


def test_euler_decomposition_round_trips() -> None:
    R = rot_x(math.radians(0.7)) @ rot_y(math.radians(-0.4)) @ rot_z(math.radians(12.0))
    np.testing.assert_allclose(euler_xyz(R), (0.7, -0.4, 12.0), atol=1e-12)


def test_reference_pose_puts_the_crossing_on_the_optical_axis_in_focus() -> None:
    world = World(PERFECT)
    pose = world.pose()
    assert abs(pose.x_mm) < 1e-9
    assert abs(pose.y_mm) < 1e-9
    assert abs(pose.z_mm) < 1e-9
    assert pose.rotation_deg == pytest.approx(PERFECT.artifact_rotation_deg)
    np.testing.assert_allclose(centre(world), [319.5, 239.5], atol=0.01)


@pytest.mark.parametrize(("dx", "dy"), [(0.0508, 0.0), (0.0, 0.0254), (0.1016, -0.0508)])
def test_table_move_of_d_moves_the_image_by_d_times_the_scale(dx: float, dy: float) -> None:
    """+d on the table moves the crossing by px_per_mm * d along the table axes as the camera sees them."""
    world = World(PERFECT)
    before = centre(world, 1)
    world.set_table_readings(dx, dy)
    after = centre(world, 2)
    phi = math.radians(PERFECT.table_rotation_deg)
    expected = PERFECT.camera.px_per_mm * np.array(
        [dx * math.cos(phi) - dy * math.sin(phi), dx * math.sin(phi) + dy * math.cos(phi)]
    )
    np.testing.assert_allclose(after - before, expected, atol=0.01)


def test_table_imperfections_backlash_and_resolution() -> None:
    world = World(WorldSpec(table=TableImperfections(skew_deg=0.0, resolution_in=0.0002, backlash_mm=0.002)))
    world.set_table_readings(0.0254, 0.0)  # 5 divisions, moving +x: lags by half the backlash
    assert world.table_position_mm()[0] == pytest.approx(0.0254 - 0.001)
    world.set_table_readings(0.01524, 0.0)  # 3 divisions, reversing: now ahead by half the backlash
    assert world.table_position_mm()[0] == pytest.approx(0.01524 + 0.001)
    world.set_table_readings(0.0140, 0.0)  # between divisions (still -x): the thimble stops on 3
    assert world.table_position_mm()[0] == pytest.approx(0.01524 + 0.001)
    assert world.table_readings_mm() == (0.0140, 0.0)


def test_joint_move_shifts_the_image_as_the_kinematics_predict() -> None:
    q = list(PERFECT.reference_joints_deg)
    world = World(PERFECT, joints=lambda: q)
    before = centre(world, 3)
    q[0] += 0.02  # joint 1 swings the camera sideways
    after = centre(world, 4)
    # prediction from the kinematics alone: the artifact origin seen from the moved camera
    cam = world.kinematics.forward(q, tool=True)
    origin = world.artifact_pose()[:3, 3]
    p = np.linalg.inv(cam) @ np.append(origin, 1.0)
    f = world.spec.camera.focal_px
    predicted = np.array([f * p[0] / p[2] + 319.5, f * p[1] / p[2] + 239.5])
    np.testing.assert_allclose(after, predicted, atol=0.01)
    assert np.hypot(*(after - before)) > 10.0  # 0.02 deg at ~480 mm reach is ~0.17 mm: ~17 px


def test_defocus_blurs_the_image() -> None:
    q = list(PERFECT.reference_joints_deg)
    world = World(PERFECT, joints=lambda: q)
    sharp = world.preset_for(world.pose()).blur_sigma_px
    q[1] += 0.05  # shoulder: the camera moves along its axis too
    assert abs(world.pose().z_mm) > 0.01
    assert world.preset_for(world.pose()).blur_sigma_px > sharp


def test_sim_camera_frames_are_new_and_measurable() -> None:
    camera = SimCamera(World(PERFECT), frame_rate_hz=0.0)
    assert isinstance(camera, Camera)
    with pytest.raises(DeviceConnectionError, match="not open"):
        camera.grab()
    with camera:
        a, b = camera.grab_many(2)
        assert a.frame_id != b.frame_id
        assert not np.array_equal(a.image, b.image)  # new noise every frame
        avg = camera.grab_many(4, average=True)[0]
        assert avg.averaged == 4
        np.testing.assert_allclose(measure(avg.image).center_px, [319.5, 239.5], atol=0.01)
        camera.set_roi(Roi(100, 50, 320, 240))
        assert camera.grab().image.shape == (240, 320)
        with pytest.raises(InvalidSettingError):
            camera.set_roi(Roi(500, 0, 320, 240))
        camera.set_roi(None)
        dim = camera.set_exposure_us(5000.0)
        assert dim == 5000.0
        assert camera.grab().image.mean() < a.image.mean()


def test_sim_operator_turns_the_micrometers_when_prompted() -> None:
    broker = PromptBroker()
    world = World(PERFECT)
    with SimOperator(broker, world):
        handle = broker.ask(
            "set X to 0.0010 in, Y to 0.0020 in, then confirm",
            kind="table.move",
            fields=(PromptField("x_in", "X", "in", 0.001), PromptField("y_in", "Y", "in", 0.002)),
        )
        answer = handle.wait(timeout=5.0)
    assert answer.confirmed
    assert dict(answer.readings) == {"x_in": 0.001, "y_in": 0.002}
    np.testing.assert_allclose(world.table_position_mm(), (0.0254, 0.0508))
