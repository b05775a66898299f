"""The calibration plan's configurations along the cell's rulers (issue 22, item 5): built to match the
configuration the bench proved (``sim.calibration_rulers.RulerPlan``), absent for a cell without rulers
and for a session that names its placements."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from sim.calibration_rulers import RulerPlan
from sim.station import build_sim_station
from station.config import StationDevices
from station.kinds import get_plan
from station.kinds.calibration.params import CalibrationCell, CalibrationParams
from station.kinds.calibration.ruler_plan import LATERAL_MM, LEAN_AZIMUTHS_DEG, TURN_JITTER_DEG, ruler_frame
from station.plans import (
    Align,
    Capture,
    MoveAligned,
    MoveJoints,
    PlanContext,
    PlanError,
    Settle,
    parse_params,
)
from station.plans._ruler import is_ruler
from station.vision import MeasureParams


@pytest.fixture(scope="module")
def devices() -> Iterator[StationDevices]:
    d = build_sim_station(seed=0)
    yield d
    d.close_owned()


def cell_of(devices: StationDevices, *, rulers: bool = True) -> CalibrationCell:
    config: dict[str, Any] = devices.config.model_dump(mode="json")
    if not rulers:
        config["calibration"]["rulers"] = []
    cell = get_plan("calibration").cell_from_config(config, MeasureParams())  # type: ignore[attr-defined]
    assert cell is not None
    return cell


def test_the_defaults_are_the_benchs_ruler_plan() -> None:
    bench, p = RulerPlan(), CalibrationParams()
    assert tuple(p.ruler_positions_mm) == bench.positions_mm
    assert tuple(p.ruler_turns_deg) == bench.turns_deg
    assert p.ruler_solutions == bench.max_solutions
    assert tuple(p.ruler_depth_offsets_mm) == bench.depth_offsets_mm
    assert tuple(p.ruler_depth_positions_mm) == bench.depth_positions_mm
    assert p.ruler_lean_deg == bench.lean_deg
    assert tuple(p.ruler_lean_positions_mm) == bench.lean_positions_mm
    assert bench.lean_azimuths_deg == LEAN_AZIMUTHS_DEG
    assert (bench.turn_jitter_deg, bench.lateral_mm) == (TURN_JITTER_DEG, LATERAL_MM)


def test_the_sim_cell_has_its_rulers_and_the_full_plan_frames_them_as_the_bench(
    devices: StationDevices,
) -> None:
    plan = get_plan("calibration")
    cell = cell_of(devices)
    assert [r.name for r in cell.rulers] == [m.name for m in devices.truth.world.spec.rulers]
    params = parse_params(plan, {})
    crossings = plan.configurations(params, cell)  # type: ignore[attr-defined]
    frames = plan.ruler_configurations(params, cell)  # type: ignore[attr-defined]
    # the bench's 208 frames (true arm, rulers moved by up to 1 mm); the nominal arm reaches a few less
    assert 195 <= len(frames) <= 216, len(frames)
    assert set(Counter(f.ruler for f in frames)) == {0, 1, 2}
    assert [f.index for f in frames] == list(range(len(crossings), len(crossings) + len(frames)))
    # every frame square on its ruler (or leaning 15 deg) at the working distance, over the planned point
    for f in frames:
        r = cell.rulers[f.ruler]
        F = ruler_frame(r.origin_mm, r.direction, r.normal)
        axis = f.camera_pose[:3, 2]
        lean = np.degrees(np.arccos(np.clip(axis @ F[:3, 2], -1.0, 1.0)))
        assert lean == pytest.approx(15.0 if f.lean_azimuth_deg is not None else 0.0, abs=1e-6)
        o = f.camera_pose[:3, 3]
        distance = (F[:3, 2] @ (F[:3, 3] - o)) / (F[:3, 2] @ axis)
        assert distance == pytest.approx(cell.working_distance_mm + f.depth_mm, abs=1e-6)
        s, t, _ = F[:3, :3].T @ (o + distance * axis - F[:3, 3])
        assert s == pytest.approx(f.position_mm, abs=1e-6)
        assert abs(t) <= LATERAL_MM + 1e-9
    steps = list(plan.steps(params, PlanContext(measure_params=MeasureParams(), cell=cell)))
    captures = [a for s in steps for a in s.actions if isinstance(a, Capture) and is_ruler(a.meta)]
    assert len(captures) == len(frames)
    # every frame re-centred: its step first aligns on the ruler at a named view, then each frame goes to
    # its planned joints and from there to the re-centred pose (MoveAligned, planned = those joints)
    for s in (s for s in steps if any(isinstance(a, Capture) and is_ruler(a.meta) for a in s.actions)):
        views = {a.view for a in s.actions if isinstance(a, Align)}
        assert views, s.name
        assert "" not in views, s.name
        last: Any = None
        for a in s.actions:
            if isinstance(a, Capture):
                assert isinstance(last, MoveAligned), s.name
            elif isinstance(a, MoveAligned):
                assert isinstance(last, MoveJoints), s.name
                assert last.target_deg == a.planned_deg, s.name
            if not isinstance(a, Settle):
                last = a


def test_a_cell_without_rulers_and_a_session_naming_its_placements_take_no_ruler_frames(
    devices: StationDevices,
) -> None:
    plan = get_plan("calibration")
    bare = cell_of(devices, rulers=False)
    full = parse_params(plan, {})
    assert plan.ruler_configurations(full, bare) == []  # type: ignore[attr-defined]
    ctx = PlanContext(measure_params=MeasureParams(), cell=bare)
    assert all(not is_ruler(s.meta) for s in plan.steps(full, ctx))
    named = parse_params(plan, {"placements": [0]})
    assert plan.ruler_configurations(named, cell_of(devices)) == []  # type: ignore[attr-defined]
    asked = parse_params(plan, {"placements": [0], "rulers": [1], "ruler_positions_mm": [5.0, 245.0]})
    frames = plan.ruler_configurations(asked, cell_of(devices))  # type: ignore[attr-defined]
    assert {f.ruler for f in frames} == {1}


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"rulers": [7]}, "ruler 7 is not in the cell"),
        ({"ruler_positions_mm": [5.0, 300.0]}, "off it"),
    ],
)
def test_a_ruler_plan_the_cell_cannot_take_says_what_to_change(
    devices: StationDevices, values: dict[str, Any], message: str
) -> None:
    plan = get_plan("calibration")
    with pytest.raises(PlanError, match=message):
        plan.ruler_configurations(parse_params(plan, values), cell_of(devices))  # type: ignore[attr-defined]
