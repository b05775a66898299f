"""The runner on the in-process fakes: states, control, faults, the record it leaves."""

from __future__ import annotations

import itertools
import threading
import time
from typing import Any

import numpy as np
import pytest

from station.devices import ControllerError, DeviceTimeoutError, OperatorCancelledError
from station.kinds import get_plan
from station.plans import parse_params
from station.record import Record, SessionLockError, station_lock
from station.runner import ACTIVE_STATES, SessionRunner, SessionState, reconcile
from station.testing import FakeRobot, FakeStation
from tests.sessions.conftest import EventLog, results_of, sid_of

REF = (0.0, 30.0, 60.0, 0.0, 90.0, 0.0)


def runner(record: Record, fake: FakeStation, kind: str, **params: Any) -> tuple[SessionRunner, EventLog]:
    plan = get_plan(kind)
    if kind == "repeatability":
        params.setdefault("settle_s", 0.0)  # the fake arm settles at once
    r = SessionRunner(record, plan, parse_params(plan, params), devices=fake.devices())
    log = EventLog()
    r.subscribe(log)
    return r, log


def test_repeatability_on_fakes_captures_every_cycle_and_computes_rp(
    record: Record, fake: FakeStation
) -> None:
    r, log = runner(record, fake, "repeatability", cycles=4, warmup_cycles=1, joints=[1, 3])
    assert r.run() is SessionState.SUCCEEDED
    sid = sid_of(r)
    row = record.get_session(sid)
    assert row.state == "succeeded"
    assert row.error is None
    caps = record.captures(sid)
    assert len(caps) == 2 * (1 + 4)  # a reference and four cycles per test
    assert [c.meta["role"] for c in caps[:5]] == ["reference", "cycle", "cycle", "cycle", "cycle"]
    assert all(m.result["ok"] for m in record.measurements(sid))
    results = results_of(record, r)
    assert set(results["rp_mm"]) == {"J1", "J3"}
    # the fake arm returns exactly: the measured scatter is the camera noise only, well under 1 um
    assert all(0 <= rp < 0.001 for rp in results["rp_mm"].values())
    assert results["tests"]["J1"]["n_cycles"] == 4
    # every motion went through move_joints, and the arm ends at the reference
    assert fake.robot.calls_of("set_speed") == [(80,)]
    assert tuple(fake.robot.joints) == REF
    # before pre-flight the session asked for the cross on the table (the fake's operator confirmed it)
    assert log.states() == ["running", "awaiting_operator", "running", "succeeded"]
    assert [e.data["content"] for e in log.of("table_content")] == ["cross"]
    assert all(s.state == "done" for s in record.steps(sid))
    assert r.progress().done == r.progress().total == 2 * (1 + 1 + 4)


def test_events_have_per_session_sequence_and_increasing_ids(record: Record, fake: FakeStation) -> None:
    r, log = runner(record, fake, "repeatability", cycles=3, warmup_cycles=0, joints=[2])
    r.run()
    events = record.events(sid_of(r))
    assert [e.seq for e in events] == list(range(1, len(events) + 1))
    assert all(a.id < b.id for a, b in itertools.pairwise(events))
    assert [e.id for e in log.events] == [e.id for e in events]
    kinds = {e.type for e in events}
    assert {"state", "step_started", "step_finished", "image_captured", "measurement", "preflight"} <= kinds


def test_validation_on_fakes_compares_with_the_pattern(record: Record, fake: FakeStation) -> None:
    r, _ = runner(record, fake, "validation", steps_per_side=3)
    assert r.run() is SessionState.SUCCEEDED
    res = results_of(record, r)
    assert res["n_positions"] == 12
    assert res["mean_um"] < 0.2
    assert res["max_um"] < 0.5
    assert abs(res["scale"] - 1.0) < 0.005
    assert res["scale_calibration"]["session_id"] == sid_of(r)
    # same-direction approach: an overshoot before the first position and before every backwards step
    moves = fake.table.calls_of("move_to")
    overshoots = len(moves) - 12
    assert overshoots == 1 + 3 + 2  # the first position, three steps in -x, two in -y (no return)


def test_direct_approach_moves_once_per_position(record: Record, fake: FakeStation) -> None:
    r, _ = runner(record, fake, "validation", steps_per_side=2, approach="direct")
    assert r.run() is SessionState.SUCCEEDED
    assert len(fake.table.calls_of("move_to")) == 8
    assert results_of(record, r)["scale_calibration"] is None


def test_preflight_reports_every_problem_and_moves_nothing(record: Record) -> None:
    fake = FakeStation(robot=FakeRobot(REF, max_step_deg=5.0))
    r, _log = runner(record, fake, "repeatability", cycles=3, joints=[1, 2], delta_deg=10)
    assert r.run() is SessionState.FAILED
    row = record.get_session(sid_of(r))
    error = row.error or ""
    assert "pre-flight found" in error
    assert "J1" in error
    assert "J2" in error
    fake.robot.assert_not_called("move_joints")
    fake.robot.assert_not_called("set_speed")
    assert record.captures(sid_of(r)) == []


def test_preflight_refuses_an_unpowered_arm(record: Record) -> None:
    fake = FakeStation(robot=FakeRobot(REF, powered=False, homed=False))
    r, _ = runner(record, fake, "repeatability", cycles=3, joints=[1])
    assert r.run() is SessionState.FAILED
    error = record.get_session(sid_of(r)).error or ""
    assert "power is off" in error
    assert "not homed" in error
    fake.robot.assert_not_called("move_joints")


def test_pause_waits_at_a_safe_point_and_resume_continues(record: Record, fake: FakeStation) -> None:
    r, log = runner(record, fake, "repeatability", cycles=3, warmup_cycles=0, joints=[1])
    paused = threading.Event()
    moved_while_paused = threading.Event()

    def on_event(e: Any) -> None:
        if e.type == "step_finished" and e.data["index"] == 0:
            r.pause()
        if e.type == "state":
            if e.data["state"] == "paused":
                paused.set()
            elif paused.is_set():
                paused.clear()
        if paused.is_set() and e.type in {"step_started", "step_finished", "position"}:
            moved_while_paused.set()  # a step went on while paused: the runner did not wait

    r.subscribe(on_event)
    thread = r.start()
    assert paused.wait(30)
    done_while_paused = r.progress().done
    assert not moved_while_paused.wait(0.2)
    assert r.progress().done == done_while_paused
    assert r.state is SessionState.PAUSED
    r.resume()
    thread.join(60)
    assert r.state is SessionState.SUCCEEDED
    asked = ["running", "awaiting_operator"]  # the cross on the table, confirmed before pre-flight
    assert log.states() == [*asked, "running", "pausing", "paused", "running", "succeeded"]


def test_stop_finishes_the_step_and_returns_to_the_reference(record: Record, fake: FakeStation) -> None:
    r, log = runner(record, fake, "repeatability", cycles=10, warmup_cycles=0, joints=[1])
    # asked while step 3 runs (its start is reported from the runner's thread): step 3 is finished
    r.subscribe(lambda e: r.stop() if e.type == "step_started" and e.data["index"] == 3 else None)
    assert r.run() is SessionState.STOPPED
    sid = sid_of(r)
    assert fake.robot.calls_of("move_joints")[-1] == (REF,)
    assert [s.state for s in record.steps(sid)] == ["done"] * 4
    assert len(record.captures(sid)) == 4
    assert fake.robot.connected is False
    assert fake.cam.connected is False
    assert "stopping" in log.states()
    assert log.states()[-1] == "stopped"
    assert record.get_session(sid).state == "stopped"


def test_abort_mid_motion_stops_the_robot_and_moves_nothing_more(record: Record) -> None:
    fake = FakeStation(robot=FakeRobot(REF, move_time_s=0.0))
    r, log = runner(record, fake, "repeatability", cycles=10, warmup_cycles=0, joints=[1])

    def on_event(e: Any) -> None:
        if e.type == "step_started" and e.data["index"] == 3:
            fake.robot.move_time_s = 30.0  # step 3's motion takes long: abort lands in it
            threading.Timer(0.2, r.abort).start()

    r.subscribe(on_event)
    t0 = time.monotonic()
    assert r.run() is SessionState.ABORTED
    assert time.monotonic() - t0 < 20  # not the 30 s motion
    fake.robot.assert_called("stop")
    moves_after_stop = fake.robot.calls[[c[0] for c in fake.robot.calls].index("stop") :]
    assert not [c for c in moves_after_stop if c[0] == "move_joints"]
    sid = sid_of(r)
    assert record.get_session(sid).state == "aborted"
    assert len(record.captures(sid)) == 3  # everything captured before the abort is kept
    assert fake.robot.stopped  # the latch stays set: nothing moves until someone clears it
    assert log.states()[-2:] == ["aborting", "aborted"]


def test_controller_error_fails_the_session_and_keeps_the_captures(record: Record, fake: FakeStation) -> None:
    fake.robot.fail_on(
        "move_joints", ControllerError("Joint 1 limit", controller_text="Joint 1 limit"), nth=4
    )
    r, log = runner(record, fake, "repeatability", cycles=5, warmup_cycles=0, joints=[1])
    assert r.run() is SessionState.FAILED
    row = record.get_session(sid_of(r))
    assert "Joint 1 limit" in (row.error or "")
    fake.robot.assert_called("stop")
    assert log.of("position"), "the position is read again after a motion error"
    steps = record.steps(sid_of(r))
    assert steps[-1].state == "failed"
    assert all(s.state == "done" for s in steps[:-1])
    assert len(record.captures(sid_of(r))) == len([s for s in steps if s.state == "done"])


def test_camera_timeout_fails_the_session(record: Record, fake: FakeStation) -> None:
    fake.cam.fail_on("grab", DeviceTimeoutError("no frame within 2 s"), nth=2)
    r, _ = runner(record, fake, "repeatability", cycles=3, warmup_cycles=0, joints=[1])
    assert r.run() is SessionState.FAILED
    assert "no frame within 2 s" in (record.get_session(sid_of(r)).error or "")
    assert len(record.captures(sid_of(r))) == 1


def test_operator_cancel_fails_the_validation_with_the_reason(record: Record, fake: FakeStation) -> None:
    fake.table.fail_on("move_to", OperatorCancelledError("the operator cancelled the move"), nth=3)
    r, _ = runner(record, fake, "validation", steps_per_side=2)
    assert r.run() is SessionState.FAILED
    row = record.get_session(sid_of(r))
    assert "cancelled" in (row.error or "")
    assert len(record.captures(sid_of(r))) >= 1


def test_disk_full_fails_cleanly_without_a_half_written_capture(
    record: Record, fake: FakeStation, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The third image write hits ENOSPC in os.write: the session fails with the message, the record
    keeps the two earlier captures with their measurements, and no temporary file is left."""
    import errno
    import os

    from station.record import _images

    real_write = os.write
    calls = {"n": 0}

    def write(fd: int, data: Any) -> int:
        calls["n"] += 1
        if calls["n"] == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)

    monkeypatch.setattr(_images.os, "write", write)
    r, _ = runner(record, fake, "repeatability", cycles=5, warmup_cycles=0, joints=[1])
    assert r.run() is SessionState.FAILED
    row = record.get_session(sid_of(r))
    assert "No space left on device" in (row.error or "")
    caps = record.captures(sid_of(r))
    # the third image found the disk full: no row and no file for it; what was grabbed after it (the
    # store thread runs behind the arm) is still stored when the disk allows, never half-written
    assert [c.step_index for c in caps][:2] == [0, 1]
    assert 2 not in [c.step_index for c in caps]
    assert len(record.measurements(sid_of(r))) == len(caps)
    image_dir = record.data_dir / "images" / sid_of(r)
    on_disk = sorted(p.name for p in image_dir.iterdir())
    assert on_disk == sorted(c.path.split("/")[-1] for c in caps)  # no temporary or orphan file
    assert [s.state for s in record.steps(sid_of(r))][2] == "failed"


def test_a_second_session_is_refused_while_one_runs(record: Record, fake: FakeStation) -> None:
    with station_lock(record.data_dir, "other-session"):
        r, _ = runner(record, fake, "repeatability", cycles=3, joints=[1])
        with pytest.raises(SessionLockError, match="other-session"):
            r.run()
    assert record.list_sessions() == []
    fake.robot.assert_not_called("connect")


def test_reconcile_marks_dead_sessions_interrupted(record: Record) -> None:
    row = record.create_session("repeatability", params={}, config={}, identities={}, software={})
    record.set_state(row.id, "running")
    with station_lock(record.data_dir, "checker"):
        assert reconcile(record) == [row.id]
    assert record.get_session(row.id).state == "interrupted"
    assert SessionState.INTERRUPTED not in ACTIVE_STATES


def test_resume_skips_completed_tests_and_reruns_the_interrupted_one_from_its_start(
    record: Record, fake: FakeStation
) -> None:
    r, _ = runner(record, fake, "repeatability", cycles=4, warmup_cycles=1, joints=[1, 3])
    # J1: steps 0-5 (reference, warm-up, 4 cycles); J3: 6-11. Aborted as J3's second cycle starts.
    r.subscribe(lambda e: r.abort() if e.type == "step_started" and e.data["index"] == 9 else None)
    assert r.run() is SessionState.ABORTED
    sid = sid_of(r)
    interrupted = {c.id for c in record.captures(sid) if c.meta["test"] == "J3"}
    assert len(interrupted) == 2  # J3's reference and first cycle
    first = len(record.captures(sid))
    again = FakeStation()
    plan = get_plan("repeatability")
    row = record.get_session(sid)
    resumed = SessionRunner(
        record, plan, parse_params(plan, row.params["plan"]), devices=again.devices(), resume_session=row
    )
    log = EventLog()
    resumed.subscribe(log)
    assert resumed.run() is SessionState.SUCCEEDED
    caps = sorted(record.captures(sid), key=lambda c: c.id)
    # J1 is whole and kept; J3 runs again from its start: its reference, warm-up and all four cycles
    new = caps[first:]
    assert [(c.meta["test"], c.meta["role"], c.meta.get("run")) for c in new] == [
        ("J3", "reference", 1),
        *[("J3", "cycle", 1)] * 4,
    ]
    assert [e.data["index"] for e in log.of("step_started")][1:3] == [6, 7]  # the reference, the warm-up
    assert again.robot.calls_of("set_speed") == [(80,)]  # the session's speed, set again
    (abandoned,) = log.of("abandoned")
    assert set(abandoned.data["captures"]) == interrupted
    assert abandoned.data["steps"] == [6, 7, 8]
    test = results_of(record, resumed)["tests"]["J3"]
    assert test["n_cycles"] == 4
    assert test["partial"] is False
    assert "excluded_captures" not in test


def test_a_resumed_session_continues_its_progress_count(record: Record, fake: FakeStation) -> None:
    """Progress counts the plan's steps over the whole session: a resumed run starts from the steps that
    stay done, never from 0 of what is left (the page showed "0 / 143" after a resume). A repeatability
    reruns its interrupted test from that test's start, so the count continues from there."""
    r, _ = runner(record, fake, "repeatability", cycles=3, warmup_cycles=0, joints=[1, 2])
    r.subscribe(
        lambda e: r.abort() if e.type == "step_started" and e.data.get("name") == "J2 cycle 2" else None
    )
    assert r.run() is SessionState.ABORTED
    planned = r.progress().total
    sid = sid_of(r)
    j1_steps = sum(1 for s in record.steps(sid) if s.name.startswith("J1 "))
    assert 0 < r.progress().done < planned
    plan = get_plan("repeatability")
    row = record.get_session(sid)
    resumed = SessionRunner(
        record,
        plan,
        parse_params(plan, row.params["plan"]),
        devices=FakeStation().devices(),
        resume_session=row,
    )
    log = EventLog()
    resumed.subscribe(log)
    assert resumed.run() is SessionState.SUCCEEDED
    (event,) = log.of("resumed")
    kept = event.data["skipped_steps"]  # J1's steps: done, and not run again
    assert kept == j1_steps > 0
    counts = [
        (e.data["progress"]["done"], e.data["progress"]["total"])
        for e in log.events
        if e.type == "step_finished"
    ]
    # the prelude's step (the reference again) does not count as the plan's; J2 counts on from J1's
    assert counts[0] == (kept, planned)
    assert counts[1] == (kept + 1, planned)
    assert {total for _, total in counts} == {planned}
    assert counts[-1] == (planned, planned)
    assert [d for d, _ in counts] == sorted(d for d, _ in counts)


def test_plan_parameters_are_validated_with_the_field_named() -> None:
    from station.plans import PlanError

    plan = get_plan("repeatability")
    with pytest.raises(PlanError, match="signs"):
        parse_params(plan, {"signs": [1, 1, 1]})
    with pytest.raises(PlanError, match="joints"):
        parse_params(plan, {"joints": [7]})
    with pytest.raises(PlanError, match="speed_pct"):
        parse_params(plan, {"speed_pct": 0})
    with pytest.raises(PlanError, match="cycels"):
        parse_params(plan, {"cycels": 3})


def test_repeatability_points_spread_as_the_arm_scatters(record: Record, fake: FakeStation) -> None:
    """A fake arm that returns 0.01 deg off on joint 1 every other cycle: the captured positions show it."""
    real = fake.robot._motion
    count = {"n": 0}

    def jittery(target: Any) -> None:
        real(target)
        if tuple(target) == REF:
            count["n"] += 1
            fake.robot.joints[0] += 0.01 * (count["n"] % 2)

    fake.robot._motion = jittery  # type: ignore[method-assign]
    r, _ = runner(record, fake, "repeatability", cycles=6, warmup_cycles=0, joints=[2])
    assert r.run() is SessionState.SUCCEEDED
    pts = np.array(results_of(record, r)["tests"]["J2"]["points_mm"])
    # the scene moves the crossing by (40, 20) px per degree of joint 1: 0.01 deg -> 0.447 px -> 4.47 um
    spread = np.linalg.norm(pts[1::2].mean(axis=0) - pts[0::2].mean(axis=0))
    assert 0.0040 < spread < 0.0050
