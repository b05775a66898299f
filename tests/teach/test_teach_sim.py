"""Teaching against the simulated station's truth (issue 23, item 4): the reference pose, an artifact and
the sensor mount, from the station's own readings, within 0.1 mm / 0.1 deg of what ``sim.station``
computes from its true arm (``taught_*`` unrounded). The truth only places the arm roughly first, as a
person jogging by eye would (half a millimetre, a fifth of a degree off); it never enters the teaching."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from sim.station import (
    SIM_SENSOR_MOUNT,
    build_sim_station,
    taught_artifacts_mm,
    taught_normals,
    taught_turns_deg,
)
from station.arm_route import go_to_reference
from station.config import StationDevices
from station.jog import camera_jog_target
from station.teach import TeachRig, pose_to_see, rig_for, teach_artifact, teach_reference, teach_sensor_mount

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def station() -> Iterator[tuple[StationDevices, TeachRig]]:
    devices = build_sim_station(seed=3)
    for device in (devices.robot, devices.camera, devices.distance_sensor):
        assert device is not None
        device.connect()
    try:
        yield devices, rig_for(devices)
    finally:
        assert devices.robot is not None
        devices.robot.close()
        devices.close_owned()


def test_the_reference_pose_and_the_sensor_mount(station: tuple[StationDevices, TeachRig]) -> None:
    devices, rig = station
    truth = devices.truth.world.spec.reference_joints_deg
    q = rig.joints()  # the operator jogged near the crossing: 0.8, -0.5 mm across, 0.1 mm closer
    for axis, d in (("x", 0.8), ("y", -0.5), ("z", 0.1)):
        q = camera_jog_target(q, rig.nominal, axis, d)
    rig.move(q)
    ref = teach_reference(rig)
    np.testing.assert_allclose(ref.joints_deg, truth, atol=0.1)
    assert float(np.max(np.abs(np.subtract(ref.joints_deg, truth)))) < 0.05
    fit, pairs = teach_sensor_mount(rig)  # at the reference: square to the table and in focus
    assert fit.translation_z_mm == pytest.approx(SIM_SENSOR_MOUNT.translation_mm[2], abs=0.1)
    assert len(pairs) == 5
    assert fit.slope == pytest.approx(1.0, abs=0.03)


def test_an_artifact_on_an_angle_block(station: tuple[StationDevices, TeachRig]) -> None:
    devices, rig = station
    world = devices.truth.world
    k = 1
    position = np.array(taught_artifacts_mm(world, digits=None)[k])
    normal = np.array(taught_normals(world, digits=None)[k])
    turn = taught_turns_deg(world, digits=None)[k]
    rough_normal = normal + np.array([0.003, -0.002, 0.0])
    rough = pose_to_see(
        (20, 20, 68, 20, 95, 177),
        rig.nominal,
        position + np.array([0.5, -0.4, 0.1]),
        rig.working_distance_mm,
        normal=rough_normal / np.linalg.norm(rough_normal),
        turn_deg=turn + 3.0,
    )
    assert devices.robot is not None
    go_to_reference(devices.robot, tuple(round(float(v), 3) for v in rough), max_step_deg=27.0)
    art = teach_artifact(rig)
    np.testing.assert_allclose(art.position_mm, position, atol=0.1)
    angle = np.degrees(np.arccos(np.clip(np.dot(art.normal, normal / np.linalg.norm(normal)), -1.0, 1.0)))
    assert angle < 0.1
    assert art.turn_deg == pytest.approx(turn, abs=0.1)
