"""Finding 3 of issue 19 through the API: after an aborted calibration (the arm left over a bench artifact)
or a manual jog, sessions start at the reference pose along the arm's route, a validation (which never
moves the arm) is refused at pre-flight with what to do, ``to-reference`` brings the arm back with its
moves in the reply, and a validation then succeeds; the camera gives a frame at every pose and the
snapshot of one that cannot be measured is a 200 frame with the measurement's error beside it."""

from __future__ import annotations

import json
import time

import cv2
import httpx
import numpy as np

from station.arm_route import travel
from station.runner import PRELUDE_BASE
from station.worker import SessionHost
from tests.api.conftest import Served, ServeFactory, acknowledge_stop, wait_final

REFERENCE = [0.0, 30.0, 60.0, 0.0, 90.0, 0.0]  # the simulated station's reference pose
STEP_LIMIT = 27.0  # the sim's max_step_deg (30) less the route's 10 % margin
LIFT = (0.0, 0.0, 0.0, 0.0, 90.0, 0.0)  # upper arm and forearm upright: the camera sees no artifact
# two configurations over the first bench artifact (one branch, two turns): an abort after the first
# leaves the arm over that artifact
CALIBRATION = {
    "kind": "calibration",
    "params": {"placements": [1], "turns_deg": [-20.0, 70.0], "solutions": 1, "settle_s": 0.0},
}
PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0], [127.0, 127.0]]
VALIDATION = {"kind": "validation", "params": {"pattern_um": PATTERN}}
REPEATABILITY = {"kind": "repeatability", "params": {"cycles": 3, "joints": [1], "warmup_cycles": 0}}


# ------------------------------------------------------------------ in the station's worker (truth, jogs)


def seen_artifact(host: SessionHost) -> int:
    """Which artifact the simulated camera looks at now (0: the table's; 1-4: the bench's)."""
    world = host.devices.truth.world
    return int(world.seen_artifact(world.camera_pose()))


def jog(host: SessionHost, target: tuple[float, ...]) -> None:
    """A person with the teach pendant: the arm moved outside any session (up, across, down)."""
    robot = host.devices.robot
    robot.connect()
    try:
        for q in travel(robot.where().commanded_joints_deg, target, STEP_LIMIT):
            robot.move_joints(q)
    finally:
        robot.close()


# ------------------------------------------------------------------ helpers


def abort_calibration_over_a_bench_artifact(served: Served, c: httpx.Client) -> str:
    r = c.post("/api/v1/sessions", json=CALIBRATION)
    assert r.status_code == 201, r.text
    sid = str(r.json()["id"])
    wait_over_the_first_artifact(served, sid)
    assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
    assert wait_final(c, sid)["state"] == "aborted"
    # the abort latched the robot's stop: a person at the station acknowledges it before anything moves
    assert "stop" in acknowledge_stop(c)["reason"]
    return sid


def wait_over_the_first_artifact(served: Served, sid: str) -> None:
    """Until the session's first configuration has begun (after its route to the reference pose, if any) and
    the arm is over the first bench artifact (truth): an abort then lands in one of the two configurations
    there. (Progress counts the
    plan's steps only, and the second configuration may end before an abort sent after the first.)"""
    # the first configuration has begun (after the route), and the arm has reached it
    while not (
        any(s.index < PRELUDE_BASE for s in served.service.record.steps(sid))
        and served.service.in_worker(seen_artifact) == 1
    ):
        time.sleep(0.02)


def step_names(served: Served, sid: str) -> list[str]:
    """The session's steps in the order they ran (from the record)."""
    return [s.name for s in sorted(served.service.record.steps(sid), key=lambda s: s.started_at)]


def assert_a_route(moves: list[list[float]], start: list[float], end: list[float]) -> None:
    """Joint steps within the driver's limit from ``start``, through the lift pose, ending at ``end``."""
    previous = np.array(start)
    for q in moves:
        assert np.max(np.abs(np.array(q) - previous)) <= STEP_LIMIT + 1e-9
        previous = np.array(q)
    assert moves[-1] == end
    assert any(q[1] == 0.0 and q[2] == 0.0 for q in moves)  # upper arm and forearm upright on the way


# ------------------------------------------------------------------ the tests


def test_after_an_aborted_calibration_sessions_start_at_the_reference_and_to_reference_brings_the_arm_back(
    make_served: ServeFactory,
) -> None:
    served = make_served()
    scale_file = served.service.record.data_dir / "scale-calibration.json"
    with served.client() as c:
        abort_calibration_over_a_bench_artifact(served, c)
        assert served.service.in_worker(seen_artifact) == 1  # truth: the camera looks at a bench artifact

        # a validation never moves the arm: refused at pre-flight, saying what to do; nothing written
        r = c.post("/api/v1/sessions", json=VALIDATION)
        assert r.status_code == 422, r.text
        assert r.json()["code"] == "preflight_failed"
        problem = " ".join(r.json()["problems"])
        assert "not at its reference pose" in problem
        assert "to-reference" in problem
        assert not scale_file.exists()
        arm = c.get("/api/v1/station/robot").json()
        assert arm["at_reference"] is False
        assert arm["route"]["via_lift"] is True
        assert arm["route"]["problems"] == []

        # a repeatability starts at the reference: its first motion is the route there
        r = c.post("/api/v1/sessions", json=REPEATABILITY)
        assert r.status_code == 201, r.text
        rep = wait_final(c, r.json()["id"])
        assert rep["state"] == "succeeded", rep["error"]
        assert step_names(served, rep["id"])[0] == "to the reference pose (through the lift pose)"
        assert rep["results"]["tests"]["J1"]["failures"] == []  # every capture saw the table's crossing
        assert 0.0 < rep["results"]["rp_mm"]["J1"] < 0.1
        assert served.service.in_worker(seen_artifact) == 0

        # so does a calibration after another abort
        abort_calibration_over_a_bench_artifact(served, c)
        r = c.post("/api/v1/sessions", json=CALIBRATION)
        assert r.status_code == 201, r.text
        cal = r.json()["id"]
        wait_over_the_first_artifact(served, cal)
        assert c.post(f"/api/v1/sessions/{cal}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, cal)["state"] == "aborted"
        acknowledge_stop(c)
        assert step_names(served, cal)[:2] == [
            "to the reference pose (through the lift pose)",
            "placement 1 turn -20 solution 0",
        ]
        assert served.service.in_worker(seen_artifact) == 1

        # to-reference brings the arm back, with its moves and the final pose in the reply
        r = c.post("/api/v1/station/robot/to-reference")
        assert r.status_code == 200, r.text
        done = r.json()
        assert done["via_lift"] is True
        assert_a_route(done["moves"], done["start"]["commanded_joints_deg"], REFERENCE)
        assert done["final_pose"]["commanded_joints_deg"] == REFERENCE
        assert np.allclose(done["final_pose"]["joints_deg"], REFERENCE, atol=0.05)  # the encoders
        assert done["at_reference"] is True
        assert c.get("/api/v1/station/robot").json()["at_reference"] is True
        assert served.service.in_worker(seen_artifact) == 0

        # and a validation then succeeds, measuring the table's moves
        r = c.post("/api/v1/sessions", json=VALIDATION)
        assert r.status_code == 201, r.text
        val = wait_final(c, r.json()["id"])
        assert val["state"] == "succeeded", val["error"]
        results = val["results"]
        assert results["n_positions"] == len(PATTERN)
        # every displacement measured (in the artifact's axes, turned from the table's) to its length, and
        # the rigid fit's error at the sim table's imperfections (skew, backlash: about 1 um here)
        for p in results["positions"]:
            assert abs(np.hypot(*p["measured_um"]) - np.hypot(*p["commanded_um"])) < 3.0
        assert results["max_um"] < 3.0
        latest = c.get(f"/api/v1/sessions/{val['id']}/latest.png")
        assert (latest.status_code, latest.headers["x-measurement-ok"]) == (200, "true")
        numbers = json.loads(latest.headers["x-measurement"])  # the page's numbers under the live view
        assert numbers["ok"] is True
        assert len(numbers["center_px"]) == len(numbers["center_mm"]) == 2
        while not scale_file.exists():  # the worker writes it once the session has ended (a hang fails)
            time.sleep(0.02)


def test_to_reference_needs_the_token_and_is_refused_while_a_session_runs(make_served: ServeFactory) -> None:
    served = make_served()
    with served.client(token=False) as anonymous:
        assert anonymous.post("/api/v1/station/robot/to-reference").status_code == 401
    with served.client() as c:
        long = {"kind": "repeatability", "params": {"cycles": 5000, "joints": [1], "warmup_cycles": 0}}
        sid = c.post("/api/v1/sessions", json=long).json()["id"]
        r = c.post("/api/v1/station/robot/to-reference")
        assert r.status_code == 409
        assert sid in r.json()["detail"]
        assert c.get("/api/v1/station/robot").status_code == 409
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, sid)["state"] == "aborted"


def test_a_snapshot_where_the_camera_sees_no_artifact_is_a_frame_with_the_measurements_error(
    make_served: ServeFactory,
) -> None:
    served = make_served()
    served.service.in_worker(jog, LIFT)
    with served.client() as c:
        r = c.get("/api/v1/camera/snapshot.png", params={"overlay": True})
        assert r.status_code == 200, r.text
        assert r.headers["content-type"] == "image/png"
        assert r.headers["x-measurement-ok"] == "false"
        assert r.headers["x-measurement-code"] in {"image_quality", "edges_not_found", "bad_geometry"}
        assert r.headers["x-measurement-error"]
        numbers = json.loads(r.headers["x-measurement"])  # the same refusal, as the page reads it
        assert numbers == {
            "ok": False,
            "code": r.headers["x-measurement-code"],
            "error": r.headers["x-measurement-error"],
        }
        image = cv2.imdecode(np.frombuffer(r.content, np.uint8), cv2.IMREAD_UNCHANGED)
        assert image is not None
        assert image.shape[:2] == (480, 640)
        bottom = image[-40:].reshape(-1, 3).astype(int)  # the refusal written under the frame, in red
        assert np.any((bottom[:, 2] > 200) & (bottom[:, 1] < 150))
        plain = c.get("/api/v1/camera/snapshot.png")  # no overlay: the frame alone, nothing measured
        assert plain.status_code == 200
        assert "x-measurement-ok" not in plain.headers
        # from the lift pose the route goes straight down to the reference, where the crossing is seen
        arm = c.get("/api/v1/station/robot").json()
        assert arm["route"]["via_lift"] is True
        # one read of the arm: /station shows what GET /station/robot just read
        shown = c.get("/api/v1/station").json()["robot"]
        assert shown["commanded_joints_deg"] == arm["position"]["commanded_joints_deg"] == list(LIFT)
        assert shown["at_reference"] is False
        assert c.post("/api/v1/station/robot/to-reference").status_code == 200
        # read before the reply: /station shows the arm back at once
        back = c.get("/api/v1/station").json()["robot"]
        assert (back["state"], back["at_reference"], back["commanded_joints_deg"]) == (
            "idle",
            True,
            REFERENCE,
        )
        seen = c.get("/api/v1/camera/snapshot.png", params={"overlay": True})
        assert seen.headers["x-measurement-ok"] == "true"
