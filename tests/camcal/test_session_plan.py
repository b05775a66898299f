"""The ``camera-calibration`` kind's pieces that need no session: its views as arm moves, the camera
model's file and history, the typed class name, and that a view of the target is stored but not measured."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sim.station import build_sim_station
from station.camcal import ViewSpec
from station.camera_model import CameraIntrinsics, read_camera_model
from station.kinds import get_kind
from station.kinds.camera_calibration.model_file import DEFAULT_NAME, HISTORY_DIR, write_with_history
from station.kinds.camera_calibration.plan import (
    CameraCalibrationParams,
    CameraCell,
    camera_cell_from_config,
    moves_between,
    reading_uncertainty_mm,
    view_joints,
)
from station.plans import PlanError
from station.plans._ruler import measured
from station.resources import TypedSessionResource


@pytest.fixture(scope="module")
def cell() -> CameraCell:
    devices = build_sim_station(time_scale=1000.0)
    try:
        cell = camera_cell_from_config(devices.config.model_dump(mode="json"))
    finally:
        devices.close_owned()
    assert cell is not None  # the sim station has a robot and [calibration]
    return cell


def test_every_default_view_is_reachable_and_puts_the_camera_where_planned(cell: CameraCell) -> None:
    assert cell is not None
    assert cell.reference_joints_deg is not None
    ref = np.asarray(cell.reference_joints_deg)
    views = CameraCalibrationParams().views()
    assert len(views) == 308
    seen: set[ViewSpec] = set()
    for planned in views:
        if planned in seen:  # the square views' passes repeat their heights
            continue
        seen.add(planned)
        view, q = view_joints(cell, planned)
        assert cell.kinematics.within_limits(q)
        want = cell.kinematics.forward(ref) @ view.camera_motion(cell.working_distance_mm)
        got = cell.kinematics.forward(np.asarray(q))
        assert np.abs(got[:3, 3] - want[:3, 3]).max() < 1e-3  # mm
        assert np.abs(got[:3, :3] - want[:3, :3]).max() < 1e-5
        if view != planned:  # the twin of a tilt toward the base: the same angle to the target
            n_planned = planned.camera_motion(68.0)[:3, :3].T @ np.array([0.0, 0.0, 1.0])
            n_taken = view.camera_motion(68.0)[:3, :3].T @ np.array([0.0, 0.0, 1.0])
            assert np.degrees(np.arccos(np.clip(n_planned @ n_taken, -1, 1))) < 10.5


def test_an_unreachable_view_is_refused_with_what_to_do(cell: CameraCell) -> None:
    with pytest.raises(PlanError, match="plan smaller tilts"):
        view_joints(cell, ViewSpec(tilt_deg=55.0, azimuth_deg=90.0))


def test_moves_are_split_within_the_robots_largest_step() -> None:
    moves = moves_between((0.0,) * 6, (0.0, 0.0, 0.0, 0.0, 0.0, 90.0), 30.0)
    assert len(moves) == 4
    assert moves[-1][5] == 90.0
    steps = np.diff(np.vstack([np.zeros(6), np.asarray(moves)]), axis=0)
    assert np.abs(steps).max() <= 30.0


def test_the_readings_uncertainty_is_the_pooled_scatter_over_the_samples_averaged() -> None:
    rng = np.random.default_rng(0)
    samples = [list(50.0 + k + rng.normal(0.0, 0.002, 10)) for k in range(40)]
    assert reading_uncertainty_mm(samples) == pytest.approx(0.002 / np.sqrt(10), rel=0.1)
    assert reading_uncertainty_mm([[50.0]]) == 0.001  # one sample a view: no scatter to pool


def test_a_model_is_written_with_the_old_one_kept(tmp_path: Path) -> None:
    model = CameraIntrinsics(
        np.array([[6800.0, 0, 320], [0, 6800.0, 240], [0, 0, 1]]), np.zeros(5), (640, 480)
    )
    first = write_with_history(model, None, tmp_path)
    assert first.path == tmp_path / DEFAULT_NAME
    assert first.previous is None
    assert not first.configured
    second_model = CameraIntrinsics(model.camera_matrix * [[1.01], [1.01], [1]], np.zeros(5), (640, 480))
    configured = tmp_path / "cfg" / "camera.json"
    configured.parent.mkdir()
    configured.write_text(json.dumps(model.to_dict()))
    second = write_with_history(second_model, configured, tmp_path)
    assert second.path == configured
    assert second.configured
    assert second.previous == tmp_path / HISTORY_DIR / "0001.json"
    assert read_camera_model(second.previous).fx == pytest.approx(6800.0)  # the old one, kept
    assert read_camera_model(configured).fx == pytest.approx(6868.0)
    third = write_with_history(model, configured, tmp_path)
    assert third.previous == tmp_path / HISTORY_DIR / "0002.json"  # never overwritten


def test_the_kinds_typed_class_names_split_on_the_hyphen() -> None:
    from typing import get_args

    kind = get_kind("camera-calibration")
    assert kind.plan.scale_check == "skip"  # type: ignore[attr-defined]
    names = {t.__name__ for t in get_args(get_args(TypedSessionResource)[0])}
    assert "CameraCalibrationSession" in names


def test_a_view_of_the_target_is_stored_but_not_groove_measured() -> None:
    assert not measured({"artifact": "target"})
    assert measured({"artifact": "ruler"})
    assert measured({})


def test_a_resumed_session_goes_from_the_reference_pose_to_where_the_next_view_starts(
    cell: CameraCell,
) -> None:
    from station.kinds.camera_calibration.plan import CAMERA_CALIBRATION
    from station.plans import MoveJoints, PlanContext
    from station.vision import MeasureParams

    params = CameraCalibrationParams()
    ctx = PlanContext(
        measure_params=MeasureParams(), reference_joints_deg=cell.reference_joints_deg, cell=cell
    )
    steps = list(CAMERA_CALIBRATION.steps(params, ctx))
    assert CAMERA_CALIBRATION.resume_prelude(params, ctx, steps[0]) == []
    (prelude,) = CAMERA_CALIBRATION.resume_prelude(params, ctx, steps[12])
    moves = [a.target_deg for a in prelude.actions if isinstance(a, MoveJoints)]
    previous = [a.target_deg for a in steps[11].actions if isinstance(a, MoveJoints)][-1]
    assert moves[-1] == previous  # where step 12's own moves start
    path = np.vstack([np.asarray(cell.reference_joints_deg), np.asarray(moves)])
    assert np.abs(np.diff(path, axis=0)).max() <= cell.max_step_deg


def test_a_square_view_below_the_last_is_approached_from_below(cell: CameraCell) -> None:
    """Every square view of a turn is reached moving away from the target: the joints' backlash then
    sits on one side for all of them, where it would otherwise tilt the low and the high views apart
    (the sensor beside the axis reads the tilt as height)."""
    from station.kinds.camera_calibration.plan import APPROACH_MM, CAMERA_CALIBRATION
    from station.plans import MoveJoints, PlanContext
    from station.vision import MeasureParams

    params = CameraCalibrationParams(square_turns_deg=[45.0], square_passes=2, azimuths=1)
    ctx = PlanContext(
        measure_params=MeasureParams(), reference_joints_deg=cell.reference_joints_deg, cell=cell
    )
    steps = list(CAMERA_CALIBRATION.steps(params, ctx))
    heights = [s.meta["height_mm"] for s in steps[:5]]
    assert heights == [0.0, -1.5, 1.5, -1.5, 1.5]
    ref = np.asarray(cell.reference_joints_deg)
    for step in steps[1:5]:
        moves = [a.target_deg for a in step.actions if isinstance(a, MoveJoints)]
        view = params.views()[step.index]
        camera = [
            float(np.linalg.solve(cell.kinematics.forward(ref), cell.kinematics.forward(q))[2, 3])
            for q in moves
        ]
        # the camera's last motion along its axis is away from the target (-z of the square pose)
        assert camera[-1] == pytest.approx(-view.height_mm, abs=1e-3)
        if len(moves) > 1:
            assert camera[-2] == pytest.approx(-(view.height_mm - APPROACH_MM), abs=1e-3)
        before = [a.target_deg for a in steps[step.index - 1].actions if isinstance(a, MoveJoints)][-1]
        last_from = moves[-2] if len(moves) > 1 else before
        z_from = float(
            np.linalg.solve(cell.kinematics.forward(ref), cell.kinematics.forward(last_from))[2, 3]
        )
        assert z_from > camera[-1]  # came from nearer the target
