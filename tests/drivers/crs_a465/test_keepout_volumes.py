"""Keep-out volumes along every path (issue 23, item 4): the cell's fixtures, the carried bodies, home."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import TypeAdapter

from drivers.crs_a465 import MotionGuard, SafetyLimits, build_robot
from sim.station import SIM_SENSOR_MOUNT, build_sim_station, sim_camera_mount, sim_safety
from sim.world import World
from station.devices import MotionRejectedError
from station.keepout import CarriedBody, KeepOut, KeepOutBox, KeepOutCylinder, volume_distance
from station.kinematics import Kinematics
from station.mounts import robot_safety_fields, rotation_xyz_deg

# Both ends clear of every fixture; joint 1's sweep between them carries the camera body through the
# plate of the simulated cell's bench artifact 2 (checked independently below).
START = (-30.0, 34.7, 59.9, -16.9, 96.3, 4.8)
SWEEP = (1, 24.0)


def sim_limits() -> SafetyLimits:
    world = World()
    fields = robot_safety_fields(sim_safety(world), sim_camera_mount(world), SIM_SENSOR_MOUNT)
    return SafetyLimits(**fields)


def camera_body_gap(limits: SafetyLimits, q: np.ndarray, volume: KeepOutBox | KeepOutCylinder) -> float:
    """Independent of the guard: the camera body's axis sampled every 2 mm, its radius taken off."""
    body = next(b for b in limits.carried if b.name == "camera body")
    flange = Kinematics().flange(q)
    a, e = np.array(body.start_mm), np.array(body.end_mm)
    points = [flange[:3, :] @ np.append(a + t * (e - a), 1.0) for t in np.linspace(0.0, 1.0, 61)]
    return float(volume_distance(volume, np.array(points)).min() - body.radius_mm)


def test_a_sweep_through_a_fixture_is_refused_though_both_ends_are_clear():
    limits = sim_limits()
    plate = next(v for v in limits.keep_out if v.name == "bench artifact 2 plate")
    end = np.array(START)
    end[SWEEP[0] - 1] += SWEEP[1]
    path = np.linspace(START, end, 241)
    assert camera_body_gap(limits, np.array(START), plate) > limits.clearance_mm + 1.0
    assert camera_body_gap(limits, end, plate) > limits.clearance_mm + 1.0
    assert min(camera_body_gap(limits, q, plate) for q in path) < -10.0  # deep through the plate
    devices = build_sim_station(start_pose_deg=START)
    try:
        robot = devices.robot
        assert robot is not None
        robot.connect()
        moves = len(devices.truth.twin.motion_log)
        with pytest.raises(
            MotionRejectedError, match=r"camera body would come within .* 'bench artifact 2 plate'"
        ):
            robot.move_joint(*SWEEP)
        with pytest.raises(MotionRejectedError, match="bench artifact 2 plate"):
            robot.check_move(tuple(end))
        assert len(devices.truth.twin.motion_log) == moves  # nothing was sent
        robot.close()
    finally:
        devices.close_owned()


def test_no_sampled_path_is_called_clear_that_a_ten_times_finer_one_finds_touching():
    """The sampling's guarantee: a path the guard passes keeps every carried body at least the clearance
    from every volume at ten times its own sampling."""
    limits = sim_limits()
    guard = MotionGuard(limits)
    strict = MotionGuard(limits.model_copy(update={"path_resolution_mm": 0.2, "path_step_deg": 0.1}))
    rng = np.random.default_rng(7)
    reference = np.array((0.0, 30.0, 60.0, 0.0, 90.0, 0.0))
    passed = refused = 0
    for _ in range(150):
        a = reference + rng.uniform(-60, 60, 6) * np.array([1, 0.5, 0.5, 0.3, 0.5, 0.3])
        b = a + rng.uniform(-25, 25, 6) * rng.integers(0, 2, 6)
        if guard.keepout_violation([a]) or guard.keepout_violation([b]):
            continue
        if guard.path_violation([a, b]) is None:
            passed += 1
            assert strict.keepout_violation(np.linspace(a, b, 10 * guard.segment_samples(a, b) + 1)) is None
        else:
            refused += 1
    assert passed > 30


def test_the_carried_bodies_are_checked_not_only_the_lens_front():
    # a block beside the camera: the lens front stays far above the table plane, the body touches it
    pose = np.array((0.0, 30.0, 60.0, 0.0, 90.0, 0.0))
    flange = Kinematics().flange(pose)
    beside = flange[:3, :] @ np.array([0.0, 45.0, 60.0, 1.0])  # 45 mm off the camera's axis, mid-body
    block = KeepOutCylinder(
        name="post", base_mm=(beside[0], beside[1], 0.0), radius_mm=10.0, height_mm=beside[2] + 20
    )
    camera = CarriedBody(name="camera body", start_mm=(0, 0, 0), end_mm=(0, 0, 120), radius_mm=30.0)
    limits = SafetyLimits(keep_out=(block,), carried=(camera,), camera_offset_mm=(0, 0, 120))
    assert "camera body" in (MotionGuard(limits).keepout_violation([pose]) or "")
    thin = limits.model_copy(update={"carried": (camera.model_copy(update={"radius_mm": 2.0}),)})
    assert MotionGuard(thin).keepout_violation([pose]) is None


def test_home_is_refused_when_its_path_crosses_a_fixture():
    # a shelf above the arm: the ready pose is clear of it, the arm straight up (home) is not
    shelf = KeepOutBox(name="shelf", center_mm=(0.0, 0.0, 1150.0), size_mm=(600.0, 600.0, 40.0))
    devices = build_sim_station()
    try:
        camera = CarriedBody(name="camera body", start_mm=(0, 0, 0), end_mm=(0, 0, 100), radius_mm=30.0)
        robot = build_robot(devices.truth.port, safety=SafetyLimits(keep_out=(shelf,), carried=(camera,)))
        robot.connect()
        received = len(devices.truth.twin.received)
        with pytest.raises(MotionRejectedError, match=r"home from .*shelf"):
            robot.home()
        assert "home" not in devices.truth.twin.received[received:]
        robot.close()
    finally:
        devices.close_owned()


def test_keepout_volumes_load_from_toml_and_are_validated():
    adapter = TypeAdapter(KeepOut)
    box = adapter.validate_python({"shape": "box", "name": "t", "center_mm": [0, 0, 0], "size_mm": [2, 2, 2]})
    cyl = adapter.validate_python(
        {"shape": "cylinder", "name": "c", "base_mm": [0, 0, 0], "radius_mm": 1, "height_mm": 3}
    )
    assert isinstance(box, KeepOutBox)
    assert isinstance(cyl, KeepOutCylinder)
    np.testing.assert_allclose(volume_distance(box, [[0, 0, 0], [3, 0, 0], [2, 2, 1]]), [0, 2, np.sqrt(2)])
    np.testing.assert_allclose(
        volume_distance(cyl, [[0, 0, 1], [3, 0, 1], [0, 0, 5], [4, 0, -3]]), [0, 2, 2, np.sqrt(18)]
    )
    for bad in ({"size_mm": [0, 1, 1]}, {"shape": "sphere"}):
        with pytest.raises(ValueError, match=r"size_mm|tag"):
            adapter.validate_python(
                {"shape": "box", "name": "b", "center_mm": [0, 0, 0], "size_mm": [1, 1, 1], **bad}
            )
    with pytest.raises(ValueError, match="distinct names"):
        SafetyLimits(keep_out=(box, box))


def test_the_sim_plates_are_where_the_world_has_them():
    world = World()
    for k, T in enumerate(world.artifact_poses()):
        name = "table artifact plate" if k == 0 else f"bench artifact {k} plate"
        plate = next(v for v in sim_safety(world)["keep_out"] if v["name"] == name)
        np.testing.assert_allclose(rotation_xyz_deg(plate["rotation_deg"]), T[:3, :3], atol=1e-9)
        crossing = T[:3, 3]
        assert volume_distance(KeepOutBox(**plate), [crossing])[0] == pytest.approx(
            0.0, abs=1e-9
        )  # on its face
        above = crossing - 1.0 * T[:3, 2]  # 1 mm above the face, along the upward normal
        assert volume_distance(KeepOutBox(**plate), [above])[0] == pytest.approx(1.0, abs=1e-9)
