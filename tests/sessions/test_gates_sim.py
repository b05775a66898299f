"""Each gate catches its fault, on the simulated station (issue 19): the fault is made in the simulated
world (its truth), the session is the station's own, and the verdict is read from its results.

* an artifact that does not move with the table (an operator confirms readings, nothing moves): the
  validation stops at once, fails, and the station's scale calibration stays as it was (finding 1);
* the arm off its reference pose, over a bench artifact (what an aborted calibration leaves), with the
  reference pose taught there so that no pre-flight check can tell: the same gate stops it;
* a micrometer misread by one turn (0.025 in) at one position;
* a groove width far off the artifact's tolerance;
* the artifact knocked between two repeatability tests;
* a resumed validation whose setup moved while the station was down, and one whose setup did not;
* a clean session passes every gate, with the values the world's truth gives.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from sim.artifact import ArtifactSpec
from sim.operator import table_content_asked
from sim.station import SIM_TABLE_ORIGIN_IN, build_sim_station
from sim.world import INCH_MM, WorldSpec
from station import scale_calibration as scal
from station.config import StationDevices
from station.kinds import get_plan
from station.kinds.calibration.params import CalibrationParams, calibration_cell_from_config
from station.kinds.calibration.plan import CALIBRATION
from station.kinds.validation.gates import NOT_SEEN, SETUP_MOVED
from station.plans import parse_params
from station.prompts import Prompt
from station.record import Record
from station.runner import SessionRunner, SessionState
from station.session import run_session
from station.vision import MeasurementError, MeasureParams, measure
from tests.sessions.conftest import EventLog, results_of, sid_of

#: One turn of a micrometer thimble: 0.025 in.
TURN_MM = 0.025 * INCH_MM


@pytest.fixture
def record(tmp_path: Path) -> Iterator[Record]:
    rec = Record(tmp_path / "data")
    yield rec
    rec.close()


def checks_of(results: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {c["name"]: c for c in results["checks"]}


class FaultyOperator:
    """Answers the table's prompts in place of the simulated operator, confirming the readings asked for
    while turning the world's micrometers to ``turn(index, x_mm, y_mm)`` (None: not at all)."""

    def __init__(
        self, devices: StationDevices, turn: Callable[[int, float, float], tuple[float, float] | None]
    ) -> None:
        self.sim = devices.truth
        self.sim.operator.close()  # the station's own simulated operator steps aside
        self.broker = devices.broker
        self.turn = turn
        self.answered = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="faulty-operator", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        seen: set[str] = set()
        while not self._stop.is_set():
            prompt = self.broker.wait_for_prompt(timeout=0.05)
            if prompt is None or prompt.id in seen:
                self._stop.wait(0.005)
                continue
            seen.add(prompt.id)
            self._answer(prompt)

    def _answer(self, prompt: Prompt) -> None:
        content = table_content_asked(prompt)
        if content is not None:  # what to put on the table: that, as the simulated operator does
            self.sim.world.place_on_table(content)
            self.broker.confirm(prompt.id, by="test-operator")
            return
        asked = {f.name: float(f.requested or 0.0) for f in prompt.fields}
        x_mm = (asked["x_in"] - SIM_TABLE_ORIGIN_IN[0]) * INCH_MM
        y_mm = (asked["y_in"] - SIM_TABLE_ORIGIN_IN[1]) * INCH_MM
        where = self.turn(self.answered, x_mm, y_mm)
        if where is not None:
            self.sim.world.set_table_readings(*where)
        self.broker.confirm(prompt.id, {"x_in": asked["x_in"], "y_in": asked["y_in"]}, by="test-operator")
        self.answered += 1

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)


def validate(record: Record, devices: StationDevices, **params: Any) -> tuple[SessionRunner, EventLog]:
    plan = get_plan("validation")
    runner = SessionRunner(record, plan, parse_params(plan, params), devices=devices)
    log = EventLog()
    runner.subscribe(log)
    runner.run()
    return runner, log


def waypoints(
    start: tuple[float, ...], end: tuple[float, ...], step_deg: float = 9.0
) -> list[tuple[float, ...]]:
    """From ``start`` to ``end`` through both lift poses (upper arm and forearm upright), no joint moving
    more than ``step_deg`` at a time: the way an aborted calibration's travel goes."""
    out: list[tuple[float, ...]] = []
    here = start
    for there in ((start[0], 0.0, 0.0, *start[3:]), (end[0], 0.0, 0.0, *end[3:]), end):
        n = max(1, math.ceil(max(abs(b - a) for a, b in zip(here, there, strict=True)) / step_deg))
        out += [
            tuple(round(a + (b - a) * k / n, 3) for a, b in zip(here, there, strict=True))
            for k in range(1, n + 1)
        ]
        here = there
    return out


def park_over_a_bench_artifact(devices: StationDevices) -> tuple[float, ...]:
    """Leave the arm where an aborted calibration leaves it: square on bench artifact 1, whose crossing
    the camera measures (checked), through the driver and the controller twin; the joints."""
    cell = calibration_cell_from_config(devices.config.model_dump(mode="json"), MeasureParams())
    assert cell is not None
    robot, camera = devices.robot, devices.camera
    assert robot is not None
    robot.connect()
    camera.connect()
    try:
        for c in CALIBRATION.configurations(CalibrationParams(), cell):
            if c.placement != 1:
                continue
            for q in waypoints(tuple(robot.where().commanded_joints_deg), c.joints_deg):
                robot.move_joints(q)
            try:
                measure(camera.grab().image, MeasureParams())
            except MeasurementError:
                continue
            assert devices.truth.world.seen_artifact(devices.truth.world.camera_pose()) == 1
            return tuple(robot.where().commanded_joints_deg)
        raise AssertionError("no configuration over bench artifact 1 shows its crossing")
    finally:
        camera.close()
        robot.close()


class StillOperator:
    """The fault, in the world: the operator confirms each reading, but the artifact the camera sees does
    not move (it is not the table's, or not on the table). Installed on the session's own station."""

    def __init__(self) -> None:
        self.operator: FaultyOperator | None = None

    def __call__(self, runner: SessionRunner) -> None:
        assert runner.devices is not None
        self.operator = FaultyOperator(runner.devices, lambda i, x, y: None)

    def close(self) -> None:
        if self.operator is not None:
            self.operator.close()


@pytest.mark.timeout(300)
def test_a_validation_whose_camera_does_not_see_the_table_move_fails_and_keeps_the_scale_calibration(
    tmp_path: Path,
) -> None:
    data = tmp_path / "data"
    good = run_session("validation", sim=True, data=data)
    assert good.state == "succeeded", good.error
    path = scal.station_file(data)
    kept = path.read_bytes()
    assert scal.load(path).session_id == good.id

    still = StillOperator()
    try:
        bad = run_session("validation", sim=True, data=data, on_runner=still)
    finally:
        still.close()
    assert bad.state == "failed"
    assert str(bad.error).startswith(NOT_SEEN), bad.error
    check = checks_of(bad.results)["table_moves"]
    assert check["passed"] is False
    assert check["severity"] == "fail"
    assert check["value"] < 0.05  # the image saw (almost) nothing of the table's moves
    with Record(data) as rec:
        positions = sorted(c.meta["position"] for c in rec.captures(bad.id))
    # stopped at once: at position 5, the first 25 um or more from the start (5 x 5.08 um)
    assert positions == [0, 1, 2, 3, 4, 5]
    assert path.read_bytes() == kept  # the station's scale calibration is untouched
    assert [e.action for e in scal.history(data)] == ["validation"]


def test_the_arm_off_its_reference_over_a_bench_artifact_stops_the_validation(record: Record) -> None:
    """The arm left over bench artifact 1, and the station's reference pose taught there (so that nothing
    before the session can tell): the camera sees a crossing, but not the table's."""
    devices = build_sim_station(seed=2)
    try:
        parked = park_over_a_bench_artifact(devices)
        robot = devices.config.robot
        assert robot is not None
        devices.config = devices.config.model_copy(
            update={"robot": robot.model_copy(update={"reference_joints_deg": parked})}
        )
        runner, log = validate(record, devices)
    finally:
        devices.close_owned()
    assert runner.state is SessionState.FAILED
    assert str(runner.error).startswith(NOT_SEEN)
    positions = sorted(c.meta["position"] for c in record.captures(sid_of(runner)))
    assert positions == [0, 1, 2, 3, 4, 5]  # stopped at the first position 25 um from the start
    assert not checks_of(results_of(record, runner))["table_moves"]["passed"]
    assert [e.data["type"] for e in log.of("error")] == ["GateError"]
    assert not scal.station_file(record.data_dir).exists()  # no scale calibration from it


def test_a_micrometer_misread_by_one_turn_fails_the_rigid_fit(record: Record) -> None:
    devices = build_sim_station(seed=4)

    def one_turn_off(i: int, x: float, y: float) -> tuple[float, float]:
        return (x + TURN_MM, y) if i == 12 else (x, y)  # prompt 12: position 10 after two overshoots

    operator = FaultyOperator(devices, one_turn_off)
    try:
        runner, _ = validate(record, devices)
    finally:
        operator.close()
        devices.close_owned()
    assert runner.state is SessionState.FAILED
    res = results_of(record, runner)
    checks = checks_of(res)
    assert not checks["rigid_max"]["passed"]
    assert not checks["rigid_mean"]["passed"]
    assert checks["table_moves"]["passed"]  # the image does follow the table
    # the world's truth: one position is 635 um off, so the rigid fit's largest error is most of that
    assert 0.5 * TURN_MM * 1000 < res["max_um"] < 1.1 * TURN_MM * 1000
    assert runner.error is not None
    assert "rigid fit's largest error" in runner.error
    assert "check the micrometer readings" in runner.error


def test_a_groove_width_far_off_its_tolerance_fails_the_validation(record: Record) -> None:
    spec = replace(WorldSpec(), artifact=replace(ArtifactSpec(), groove_width_mm=0.600))
    devices = build_sim_station(spec=spec, seed=6)
    try:
        runner, _ = validate(record, devices)
    finally:
        devices.close_owned()
    assert runner.state is SessionState.FAILED
    res = results_of(record, runner)
    check = checks_of(res)["groove_width"]
    assert check["passed"] is False
    assert check["value"] == pytest.approx(0.600, rel=0.01)  # the world's true width, measured
    lo, hi = check["limit"]
    assert lo < 0.743
    assert hi > 0.7937
    assert "groove width estimate" in str(runner.error)


def test_a_clean_validation_passes_every_gate(record: Record) -> None:
    devices = build_sim_station(seed=3)
    try:
        runner, _ = validate(record, devices)
    finally:
        devices.close_owned()
    assert runner.state is SessionState.SUCCEEDED, runner.error
    res = results_of(record, runner)
    checks = checks_of(res)
    gates = {"table_moves", "groove_width", "rigid_mean", "rigid_max", "positions_measured"}
    assert set(checks) == gates | {"selftest"}  # the controller's self-test: a warning (none on record)
    checks = {name: c for name, c in checks.items() if name in gates}
    assert all(c["passed"] for c in checks.values()), checks
    assert checks["table_moves"]["value"] == pytest.approx(1.0, abs=0.05)  # the image follows the table
    assert checks["groove_width"]["value"] == pytest.approx(25.4 / 32, rel=0.002)  # the world's width
    assert checks["rigid_mean"]["limit"] == 2.0
    assert checks["rigid_max"]["limit"] == 6.0
    assert res["partial"] is False


def test_the_artifact_knocked_between_two_repeatability_tests_fails_the_session(record: Record) -> None:
    devices = build_sim_station(seed=8)
    plan = get_plan("repeatability")
    params = parse_params(plan, {"cycles": 4, "warmup_cycles": 0, "joints": [1, 3]})
    runner = SessionRunner(record, plan, params, devices=devices)

    def knock(event: Any) -> None:  # J3's reference step: steps 0-4 are J1's
        if event.type == "step_started" and event.data["index"] == 5:
            devices.truth.world.set_table_readings(0.6, 0.0)  # the table knocked 0.6 mm in x

    runner.subscribe(knock)
    try:
        assert runner.run() is SessionState.FAILED
    finally:
        devices.close_owned()
    checks = checks_of(results_of(record, runner))
    assert checks["reference:J1"]["passed"]
    assert checks["reference:J1"]["value"] == 0.0
    assert not checks["reference:J3"]["passed"]
    assert checks["reference:J3"]["value"] == pytest.approx(0.6, abs=0.02)  # the world's knock
    assert checks["rp:J1"]["passed"]
    assert checks["rp:J3"]["passed"]
    assert "the arm or the artifact moved" in str(runner.error)


@pytest.mark.parametrize(("offset_um", "succeeds"), [(0.0, True), (5.0, False)])
def test_a_resumed_validation_continues_only_where_it_left_off(
    record: Record, offset_um: float, succeeds: bool
) -> None:
    """Aborted at position 10; resumed on the same station after the artifact moved ``offset_um`` on its
    carriage (or did not): the last confirmed position is captured again and compared."""
    devices = build_sim_station(seed=9)
    shift = {"x_mm": 0.0}
    operator = FaultyOperator(devices, lambda i, x, y: (x + shift["x_mm"], y))
    try:
        first, _ = validate_until(record, devices, abort_at=10)
        assert first.state is SessionState.ABORTED
        shift["x_mm"] = offset_um / 1000.0
        plan = get_plan("validation")
        row = record.get_session(sid_of(first))
        again = SessionRunner(
            record, plan, parse_params(plan, row.params["plan"]), devices=devices, resume_session=row
        )
        log = EventLog()
        again.subscribe(log)
        final = again.run()
    finally:
        operator.close()
        devices.close_owned()
    res = results_of(record, again)
    check = checks_of(res)["resume_position"]
    assert check["value"] == pytest.approx(offset_um, abs=0.5)  # the world's shift, measured
    if succeeds:
        assert final is SessionState.SUCCEEDED, again.error
        assert check["passed"]
        assert res["n_positions"] == 40
    else:
        assert final is SessionState.FAILED
        assert again.error is not None
        assert again.error.startswith(SETUP_MOVED)
        # it stopped at once: nothing after the re-capture of position 9
        started = [e.data["name"] for e in log.of("step_started")]
        assert started == ["resume: position 9 again"]


def validate_until(
    record: Record, devices: StationDevices, *, abort_at: int
) -> tuple[SessionRunner, EventLog]:
    plan = get_plan("validation")
    runner = SessionRunner(record, plan, parse_params(plan, {}), devices=devices)
    log = EventLog()
    runner.subscribe(log)
    runner.subscribe(
        lambda e: runner.abort() if e.type == "step_started" and e.data["index"] == abort_at else None
    )
    runner.run()
    return runner, log
