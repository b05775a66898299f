"""The simulated station end to end: the real robot and table drivers move what the sim camera sees."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from drivers.crs_a465 import open_robot
from drivers.xy_table import ManualXYTable
from sim.arm_errors import FlangeErrors
from sim.station import SimStation
from sim.world import TableImperfections, WorldSpec
from station.vision import measure

PERFECT = WorldSpec(
    table=TableImperfections(skew_deg=0.0, resolution_in=0.0, backlash_mm=0.0),
    flange_errors=FlangeErrors.none(),
)


@pytest.fixture
def station() -> Iterator[SimStation]:
    with SimStation(PERFECT, repeat_sigma_deg=0.0, settle_deg=0.0) as s:
        s.camera.connect()
        yield s


def centre(station: SimStation) -> np.ndarray:
    return np.array(measure(station.camera.grab().image).center_px)


def test_a_joint_move_through_the_driver_moves_the_image_as_the_kinematics_predict(
    station: SimStation,
) -> None:
    robot = open_robot(station.port)
    robot.connect()
    try:
        before = centre(station)
        np.testing.assert_allclose(before, [319.5, 239.5], atol=0.02)
        robot.move_joint(6, 0.5)  # the wrist turns the camera about its optical axis
        robot.wait_settled(timeout_s=10.0)
        turned = measure(station.camera.grab().image)
        # the camera turns +0.5 deg about its optical axis: the artifact appears turned by -0.5 deg
        assert turned.rotation_deg == pytest.approx(PERFECT.artifact_rotation_deg - 0.5, abs=0.01)
        robot.move_joint(1, 0.01)
        robot.wait_settled(timeout_s=10.0)
        after = centre(station)
        world = station.world
        cam = world.camera_pose()
        p = np.linalg.inv(cam) @ np.append(world.artifact_pose()[:3, 3], 1.0)
        f = world.spec.camera.focal_px
        predicted = [f * p[0] / p[2] + 319.5, f * p[1] / p[2] + 239.5]
        np.testing.assert_allclose(after, predicted, atol=0.02)
        assert np.hypot(*(after - before)) > 5.0
    finally:
        robot.close()


def test_a_table_move_through_the_manual_table_moves_the_image_by_d(station: SimStation) -> None:
    table = ManualXYTable(station.broker)
    table.move_to(0.0, 0.0)
    before = centre(station)
    got = table.move_to(0.0508, 0.0254)
    assert (got.x_mm, got.y_mm) == (pytest.approx(0.0508), pytest.approx(0.0254))
    after = centre(station)
    phi = math.radians(PERFECT.table_rotation_deg)
    d = np.array([0.0508, 0.0254])
    expected = 100.0 * np.array(
        [d[0] * math.cos(phi) - d[1] * math.sin(phi), d[0] * math.sin(phi) + d[1] * math.cos(phi)]
    )
    np.testing.assert_allclose(after - before, expected, atol=0.02)
