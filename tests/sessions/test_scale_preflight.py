"""Every session's pre-flight scale check (issue 23) on the simulated station: the camera model and the
distance sensor's reading against the groove widths the camera sees, before anything moves.

The sim camera's true focal length is the nominal one (``WorldSpec.magnification_seed`` None), so a model
written from the nominal optics is right and one 1 % short is wrong by exactly 1 %.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sim.lens import nominal_intrinsics
from sim.station import build_sim_station
from station.camera_model import CameraIntrinsics, write_camera_model
from station.config import StationDevices
from station.kinds import get_plan
from station.kinematics import Kinematics
from station.plans import parse_params
from station.record import EventRow, Record
from station.runner import SessionRunner, SessionState
from station.scale_preflight import scale_check_mode
from station.teach import pose_to_see


@pytest.fixture
def record(tmp_path: Path) -> Iterator[Record]:
    rec = Record(tmp_path / "data")
    yield rec
    rec.close()


def with_model(devices: StationDevices, path: Path, model: CameraIntrinsics) -> StationDevices:
    """The station configured with ``model`` written to ``path`` as its ``[camera] camera_model``."""
    write_camera_model(model, path)
    camera = devices.config.camera.model_copy(update={"camera_model": path})
    devices.config = devices.config.model_copy(update={"camera": camera})
    return devices


def scaled(model: CameraIntrinsics, factor: float) -> CameraIntrinsics:
    K = model.camera_matrix.copy()
    K[0, 0] *= factor
    K[1, 1] *= factor
    return CameraIntrinsics(K, model.dist_coeffs, model.image_size)


def repeatability(
    record: Record, devices: StationDevices, scale_calibration: dict[str, Any] | None = None
) -> tuple[SessionRunner, list[EventRow]]:
    plan = get_plan("repeatability")
    params = parse_params(plan, {"cycles": 2, "warmup_cycles": 0, "joints": [1]})
    runner = SessionRunner(record, plan, params, devices=devices, scale_calibration=scale_calibration)
    events: list[EventRow] = []
    runner.subscribe(events.append)
    robot = devices.robot
    assert robot is not None
    try:
        runner.run()
    finally:
        devices.close_owned()
    return runner, events


def moved(events: list[EventRow]) -> bool:
    return any(e.type == "step_started" for e in events)


def of(events: list[EventRow], kind: str) -> list[dict[str, Any]]:
    return [e.data for e in events if e.type == kind]


def test_a_correct_camera_model_passes_the_scale_check(record: Record, tmp_path: Path) -> None:
    devices = with_model(build_sim_station(seed=3), tmp_path / "camera.json", nominal_intrinsics())
    runner, events = repeatability(record, devices)
    assert runner.state is SessionState.SUCCEEDED, runner.error
    (check,) = of(events, "scale_check")
    assert check["passed"] is True
    assert check["where"] == "pre-flight"
    assert check["distance_from"] == "the distance sensor"
    assert abs(check["disagreement"]) < 0.002
    assert check["model_from"].startswith("camera model ")


def test_a_focal_length_1_percent_short_is_caught_in_pre_flight(record: Record, tmp_path: Path) -> None:
    devices = with_model(build_sim_station(seed=3), tmp_path / "cam.json", scaled(nominal_intrinsics(), 0.99))
    robot = devices.robot
    assert robot is not None
    runner, events = repeatability(record, devices)
    assert runner.state is SessionState.FAILED
    assert not moved(events), "the arm moved on a session that failed its pre-flight"
    (pre,) = of(events, "preflight")
    (problem,) = pre["problems"]
    assert "scale check" in problem
    assert "station run camera-calibration" in problem  # what to do
    (check,) = of(events, "scale_check")
    assert check["passed"] is False
    # the model makes the grooves 1 % wider than the drawing allows (the true width is the nominal one)
    assert check["disagreement"] == pytest.approx(0.0101, abs=0.0015)
    assert "pre-flight" in str(runner.error)


def test_a_focal_length_1_percent_long_is_caught_against_the_scale_calibration(
    record: Record, tmp_path: Path
) -> None:
    """Against the drawing's tolerance (up to 6.4 % narrow) a model 1 % long looks like a narrow groove;
    against a scale calibration's width it does not."""
    devices = with_model(build_sim_station(seed=3), tmp_path / "cam.json", scaled(nominal_intrinsics(), 1.01))
    plan = get_plan("repeatability")
    params = parse_params(plan, {"cycles": 2, "warmup_cycles": 0, "joints": [1]})
    width = 25.4 / 32
    runner = SessionRunner(
        record,
        plan,
        params,
        devices=devices,
        scale_calibration={"groove_width_mm": width, "u_mm": 0.0004, "session_id": "v1"},
    )
    events: list[EventRow] = []
    runner.subscribe(events.append)
    try:
        runner.run()
    finally:
        devices.close_owned()
    assert runner.state is SessionState.FAILED
    assert not moved(events)
    (check,) = of(events, "scale_check")
    # 1/1.01 of the true width, less the interval's lower half-width (0.1 %): about -0.9 %
    assert -0.0115 < check["disagreement"] < -0.0065
    assert "scale calibration" in check["width_from"]


def test_a_model_for_another_image_size_is_refused(record: Record, tmp_path: Path) -> None:
    nominal = nominal_intrinsics()
    K = nominal.camera_matrix.copy()
    K[:2, 2] = (639.5, 479.5)
    devices = with_model(
        build_sim_station(seed=3), tmp_path / "camera.json", CameraIntrinsics(K, np.zeros(5), (1280, 960))
    )
    runner, events = repeatability(record, devices)
    assert runner.state is SessionState.FAILED
    assert not moved(events)
    (pre,) = of(events, "preflight")
    assert any("1280 x 960" in p and "640 x 480" in p for p in pre["problems"]), pre["problems"]
    assert of(events, "scale_check") == []  # never measured with that model


def test_a_validation_only_warns_it_measures_the_width_itself(record: Record, tmp_path: Path) -> None:
    devices = with_model(build_sim_station(seed=3), tmp_path / "cam.json", scaled(nominal_intrinsics(), 0.99))
    plan = get_plan("validation")
    params = parse_params(plan, {"pattern_um": [[0, 0], [254, 0], [0, 254]]})
    runner = SessionRunner(record, plan, params, devices=devices)
    events: list[EventRow] = []
    runner.subscribe(events.append)
    try:
        runner.run()
    finally:
        devices.close_owned()
    (check,) = of(events, "scale_check")
    assert check["passed"] is False
    assert check["severity"] == "warn"
    assert any("scale check" in w["message"] for w in of(events, "warning"))
    assert of(events, "preflight")[0]["problems"] == []


def test_off_the_crossing_the_first_capture_is_checked_and_fails_the_session(
    record: Record, tmp_path: Path
) -> None:
    """The arm away from the crossing before the session: pre-flight cannot measure the groove, so the
    session's first capture (after its route to the reference pose) is checked instead."""
    devices = with_model(build_sim_station(seed=3), tmp_path / "cam.json", scaled(nominal_intrinsics(), 0.99))
    robot = devices.robot
    assert robot is not None
    reference = devices.reference_joints_deg
    assert reference is not None
    away = (reference[0] + 8.0, *reference[1:])  # the camera looks at the bare table beside the artifact
    robot.connect()
    try:
        robot.set_speed(20)
        robot.move_joints(away)
    finally:
        robot.close()
    runner, events = repeatability(record, devices)
    assert runner.state is SessionState.FAILED
    assert of(events, "preflight")[0]["problems"] == []  # nothing to measure there: deferred
    (check,) = of(events, "scale_check")
    assert check["where"].startswith("capture ")
    assert check["passed"] is False
    assert "station run camera-calibration" in str(runner.error)
    steps = [e["name"] for e in of(events, "step_started")]
    assert len(steps) <= 2, steps  # stopped at once: the route and the first step at most


def test_a_calibration_along_the_rulers_only_warns_one_without_them_is_refused() -> None:
    """A calibration that captures along the cell's rulers identifies the magnification itself (its gate
    compares it with the grooves): the scale check only warns; one without rulers takes the camera model
    as exact, and the check refuses it."""
    plan = get_plan("calibration")
    devices = build_sim_station(seed=3)
    try:
        assert devices.config.calibration is not None
        assert devices.config.calibration.rulers  # the sim cell's three
        along = parse_params(plan, {})  # every placement and, by default, every ruler
        named = parse_params(plan, {"placements": [0, 1]})  # named placements: no rulers unless asked
        asked = parse_params(plan, {"placements": [0, 1], "rulers": [1]})
        none = parse_params(plan, {"rulers": []})
        assert scale_check_mode(plan, along, devices) == "warn"
        assert scale_check_mode(plan, asked, devices) == "warn"
        assert scale_check_mode(plan, named, devices) == "fail"
        assert scale_check_mode(plan, none, devices) == "fail"
        assert scale_check_mode(get_plan("repeatability"), None, devices) == "fail"
        assert scale_check_mode(get_plan("validation"), None, devices) == "warn"
    finally:
        devices.close_owned()


def test_an_arm_left_askew_defers_the_check_to_the_first_capture(record: Record, tmp_path: Path) -> None:
    """Where the last session left the arm (a camera calibration's tilted view), the camera sees the cross
    12 deg askew: one groove looks 2 % narrow, beyond a scale calibration's width. The check waits for the
    session's first capture, square at the reference pose, instead of refusing a right model."""
    devices = with_model(build_sim_station(seed=3), tmp_path / "camera.json", nominal_intrinsics())
    robot, reference = devices.robot, devices.reference_joints_deg
    assert robot is not None
    assert reference is not None
    nominal = Kinematics(tool=devices.config.camera_mount().matrix())
    crossing = devices.truth.world.artifact_poses()[0][:3, 3]
    tilt = math.radians(12.0)
    askew = pose_to_see(reference, nominal, crossing, 68.0, normal=(0.0, math.sin(tilt), math.cos(tilt)))
    robot.connect()
    try:
        robot.move_joints([round(float(v), 3) for v in askew])
        robot.wait_settled()
    finally:
        robot.close()
    width = {"groove_width_mm": 25.4 / 32, "u_mm": 0.0004, "session_id": "v1"}
    runner, events = repeatability(record, devices, width)
    assert runner.state is SessionState.SUCCEEDED, runner.error
    (check,) = of(events, "scale_check")
    assert check["passed"] is True
    assert check["where"].startswith("capture ")
    assert abs(check["disagreement"]) < 0.002
