"""The Z sensor twin in the simulated station: the beam's geometry, and the real driver reading the
world's true distance as the arm moves."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.distance_sensor import beam_hit
from sim.station import SIM_SENSOR_MOUNT, build_sim_station
from station.kinematics import rot_x


def _pose(R: np.ndarray, t: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def test_beam_hit_on_a_tilted_plane() -> None:
    head = _pose(np.eye(3), (0.0, 0.0, 0.0))
    tilt = math.radians(20.0)
    plane = _pose(rot_x(tilt), (0.0, 0.0, 70.0))
    hit = beam_hit(head, plane)
    assert hit.distance_mm == pytest.approx(70.0)
    assert hit.incidence_deg == pytest.approx(20.0)
    # shifted sideways along the plane's tilt: the beam meets it higher or lower by y tan(tilt)
    plane2 = _pose(rot_x(tilt), (0.0, 10.0, 70.0))
    assert beam_hit(head, plane2).distance_mm == pytest.approx(70.0 - 10.0 * math.tan(tilt))


def test_beam_pointing_away_or_plane_behind_has_no_hit() -> None:
    head = _pose(rot_x(math.pi), (0.0, 0.0, 0.0))
    assert beam_hit(head, _pose(np.eye(3), (0.0, 0.0, 70.0))).distance_mm is None
    head_up = _pose(np.eye(3), (0.0, 0.0, 100.0))
    assert beam_hit(head_up, _pose(np.eye(3), (0.0, 0.0, 70.0))).distance_mm is None


def test_the_driver_reads_the_worlds_distance_as_the_arm_moves() -> None:
    devices = build_sim_station(seed=3)
    try:
        sim = devices.truth
        sensor, robot = devices.distance_sensor, devices.robot
        assert sensor is not None
        assert robot is not None
        assert sim.distance_twin is not None
        assert devices.distance_sensor_mount is not None
        np.testing.assert_allclose(devices.distance_sensor_mount, SIM_SENSOR_MOUNT.matrix())
        sensor.connect()
        robot.connect()
        # at the reference pose the crossing is in focus: the sensor reads about the working distance
        # (30 mm beside the axis, a camera tilted a little from the level artifact reads a little off)
        wd = sim.world.spec.camera.working_distance_mm
        assert sim.distance_twin.truth().distance_mm == pytest.approx(wd, abs=0.5)
        assert np.mean([sensor.read_mm() for _ in range(20)]) == pytest.approx(
            sim.distance_twin.truth().distance_mm, abs=0.002
        )
        robot.move_joint(3, 2.0)  # the elbow: the camera rises or drops by millimetres
        truth = sim.distance_twin.truth().distance_mm
        assert truth is not None
        assert abs(truth - wd) > 0.5
        assert np.mean([sensor.read_mm() for _ in range(20)]) == pytest.approx(truth, abs=0.002)
        assert "distance_sensor" in devices.identities()
    finally:
        if devices.distance_sensor is not None:
            devices.distance_sensor.close()
        if devices.robot is not None:
            devices.robot.close()
        devices.close_owned()


def test_a_station_without_a_sensor() -> None:
    devices = build_sim_station(sensor_mount=None)
    try:
        assert devices.distance_sensor is None
        assert devices.config.distance_sensor is None
        assert devices.distance_sensor_mount is None
    finally:
        devices.close_owned()
