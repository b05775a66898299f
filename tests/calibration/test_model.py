"""The forward model is the sim's: camera poses, the crossing's pixel and the sensor's reading."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sim.artifact import homography_for
from sim.world import World, WorldSpec
from station.calibration import (
    CalibrationError,
    CalibrationModel,
    CalibrationSetup,
    CameraModel,
    Observation,
    observation_arrays,
)
from station.kinematics import A465_DH, JOINTS, transform


def _world_setup(world: World) -> tuple[CalibrationSetup, CalibrationModel, np.ndarray]:
    spec = world.spec
    camera = CameraModel.ideal(
        spec.camera.width,
        spec.camera.height,
        px_per_mm=spec.camera.px_per_mm,
        working_distance_mm=spec.camera.working_distance_mm,
    )
    art = world.artifact_pose()
    setup = CalibrationSetup(
        camera=camera,
        sensor_mount=transform(np.eye(3), (30.0, 0.0, 0.0)),
        nominal_tool=transform(np.eye(3), (0.0, 0.0, spec.tool_length_mm)),
        artifacts={0: tuple(art[:3, 3])},
        artifact_normals={0: tuple(-art[:3, 2])},
    )
    model = CalibrationModel(setup)
    delta = model.zeros()
    for i, (t, n) in enumerate(zip(world.true_dh, A465_DH, strict=True)):
        delta[4 * i : 4 * i + 4] = [
            t.alpha_deg - n.alpha_deg,
            t.a_mm - n.a_mm,
            t.d_mm - n.d_mm,
            t.theta_offset_deg - n.theta_offset_deg,
        ]
    delta[model.index["beta2"]] = world.true_dh[2].beta_deg
    return setup, model, delta


def _near_reference(world: World, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.asarray(world.spec.reference_joints_deg) + rng.uniform(-0.05, 0.05, (n, JOINTS))


def test_camera_poses_with_the_true_table_are_the_sim_worlds():
    world = World(WorldSpec())
    _, model, delta = _world_setup(world)
    q = _near_reference(world, 20, 0) + np.random.default_rng(1).uniform(-20, 20, (20, JOINTS))
    expected = np.stack([world.camera_pose_at(tuple(row)) for row in q])
    assert_allclose(model.camera_poses(delta, q), expected, rtol=0, atol=1e-9)


def test_predicted_pixel_and_reading_are_what_the_sim_camera_and_sensor_see():
    world = World(WorldSpec())
    setup, model, delta = _world_setup(world)
    q = _near_reference(world, 10, 2)
    obs = [Observation(tuple(row), (0.0, 0.0), None, i, 0) for i, row in enumerate(q)]
    px, z = model.predict(delta, observation_arrays(obs, model.placements))
    art = world.artifact_pose()
    for row, uv, reading in zip(q, px, z, strict=True):
        cam = world.camera_pose_at(tuple(row))
        H = homography_for(world.pose(np.linalg.inv(cam) @ art), world.spec.camera)
        expected = H @ np.array([0.0, 0.0, 1.0])
        assert_allclose(uv, expected[:2] / expected[2], rtol=0, atol=1e-6)
        # the beam from 30 mm beside the optical axis, parallel to it, to the artifact's plane
        head = cam @ setup.sensor_mount
        n = art[:3, 2]
        assert reading == pytest.approx(float(n @ (art[:3, 3] - head[:3, 3]) / (n @ head[:3, 2])), abs=1e-9)
    assert_allclose(z, world.spec.camera.working_distance_mm, atol=1.0)  # in focus, near the reference


def test_nominal_errors_give_the_nominal_table_and_tool():
    world = World(WorldSpec())
    setup, model, _ = _world_setup(world)
    assert model.dh(model.zeros()) == A465_DH
    assert_allclose(model.tool(model.zeros()), setup.nominal_tool)
    assert len(model.names) == 25 + 6 + 5
    assert model.names[:4] == ("alpha0", "a0", "d1", "theta1_offset")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"joints_deg": (0.0,) * 5}, "joints_deg"),
        ({"center_px": (float("nan"), 1.0)}, "center_px"),
        ({"z_mm": -1.0}, "z_mm"),
        ({"kind": "other"}, "kind"),
    ],
)
def test_rejects_a_bad_observation_naming_the_field(kwargs, message):
    base = {
        "joints_deg": (0.0,) * 6,
        "center_px": (1.0, 2.0),
        "z_mm": 68.0,
        "configuration": 0,
        "placement": 0,
    }
    with pytest.raises(CalibrationError, match=message):
        Observation(**{**base, **kwargs})


def test_rejects_observations_of_a_placement_the_setup_does_not_know():
    world = World(WorldSpec())
    _, model, _ = _world_setup(world)
    obs = [Observation((0.0,) * 6, (1.0, 2.0), 68.0, 0, 7)]
    with pytest.raises(CalibrationError, match=r"placements \[7\]"):
        observation_arrays(obs, model.placements)
