"""Issue 23 through the API: ``POST /station/robot/jog`` and ``POST /station/teach/...``, their answers and
their refusals (a bad body, a remote client, a latched stop, a running session, no configuration file),
none of which moves the arm; a teach rewrites the configuration file with its comments kept."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from sim.station import sim_fixtures
from sim.world import REFERENCE_JOINTS_DEG
from station.config import load_config
from station.worker import SessionHost
from tests.api.conftest import TOKEN, Served, acknowledge_stop, remote_client, wait_final, wait_state
from tests.api.teach_station import lab_config, served_with_config

pytestmark = pytest.mark.timeout(240)

JOG = "/api/v1/station/robot/jog"
TEACH = (
    "/api/v1/station/teach/reference",
    "/api/v1/station/teach/artifact/A",
    "/api/v1/station/teach/sensor-mount",
)
REPEATABILITY = {"kind": "repeatability", "params": {"cycles": 3, "joints": [1], "warmup_cycles": 0}}


# ------------------------------------------------------------------ in the station's worker (truth)


def camera_pose(host: SessionHost) -> list[list[float]]:
    """The simulated camera's true pose in the base frame (4x4)."""
    pose: list[list[float]] = host.devices.truth.world.camera_pose().tolist()
    return pose


def fixture_count(host: SessionHost) -> int:
    return len(sim_fixtures(host.devices.truth.world))


def sensor_head_z(host: SessionHost) -> float:
    """Where the robot's keep-out checks carry the distance sensor head: its near end's z in the flange."""
    (head,) = [b for b in host.devices.robot.guard.limits.carried if b.name == "distance sensor head"]
    return float(head.start_mm[2])


def latch(host: SessionHost) -> None:
    """A stop from the controller (as an E-stop or the stop button would): the robot's latch set."""
    robot = host.devices.robot
    robot.connect()
    try:
        robot.stop()
    finally:
        robot.close()


def commanded(c: httpx.Client) -> list[float]:
    r = c.get("/api/v1/station/robot")
    assert r.status_code == 200, r.text
    joints: list[float] = r.json()["position"]["commanded_joints_deg"]
    return joints


def problem(r: httpx.Response, status: int, code: str) -> dict[str, Any]:
    assert r.status_code == status, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    doc: dict[str, Any] = r.json()
    assert doc["code"] == code, doc
    return doc


# ------------------------------------------------------------------ jog


def test_a_joint_jog_and_a_camera_jog_move_the_simulated_arm_as_asked(served: Served) -> None:
    with served.client() as c:
        start = commanded(c)
        r = c.post(JOG, json={"mode": "joint", "joint": 1, "delta_deg": 0.5})
        assert r.status_code == 200, r.text
        doc = r.json()
        assert doc["kind"] == "joint"
        assert doc["axis"] == "1"
        assert doc["unit"] == "deg"
        assert doc["start_joints_deg"] == pytest.approx(start, abs=1e-3)
        expected = [start[0] + 0.5, *start[1:]]
        assert doc["target_joints_deg"] == pytest.approx(expected, abs=1e-3)
        assert doc["joints_deg"] == pytest.approx(expected, abs=0.01)
        assert 0 < doc["speed_pct"] <= 50
        assert len(doc["world_mm_deg"]) == 6
        assert commanded(c) == pytest.approx(expected, abs=1e-3)

        # the camera 2 mm along its own x: the true camera moves so, within the twin's repeatability (a few
        # thousandths of a degree per joint: some 0.05 mm at the camera) and the nominal model's error
        before = np.array(served.service.in_worker(camera_pose))
        r = c.post(JOG, json={"mode": "camera", "axis": "x", "delta": 2.0})
        assert r.status_code == 200, r.text
        assert r.json()["unit"] == "mm"
        after = np.array(served.service.in_worker(camera_pose))
        moved = before[:3, :3].T @ (after[:3, 3] - before[:3, 3])  # in the camera's own frame
        np.testing.assert_allclose(moved, [2.0, 0.0, 0.0], atol=0.08)
        # and turned 1 deg about its optical axis
        r = c.post(JOG, json={"mode": "camera", "axis": "turn", "delta": 1.0})
        assert r.status_code == 200, r.text
        turned = np.array(served.service.in_worker(camera_pose))
        R = after[:3, :3].T @ turned[:3, :3]
        assert np.degrees(np.arctan2(R[1, 0], R[0, 0])) == pytest.approx(1.0, abs=0.02)


BAD_BODIES: list[tuple[dict[str, Any], str]] = [
    ({"mode": "joint", "joint": 7, "delta_deg": 1.0}, "joint"),
    ({"mode": "joint", "joint": 0, "delta_deg": 1.0}, "joint"),
    ({"mode": "joint", "joint": 2, "delta_deg": 10.5}, "delta_deg"),
    ({"mode": "camera", "axis": "w", "delta": 1.0}, "axis"),
    ({"mode": "camera", "axis": "z", "delta": -11.0}, "delta"),
    ({"mode": "camera", "axis": "z", "delta": 1.0, "speed_pct": 100}, "speed_pct"),
    ({"mode": "fly", "delta": 1.0}, "mode"),
    ({"joint": 1, "delta_deg": 1.0}, "mode"),
]


def test_a_bad_jog_body_is_refused_naming_the_field_and_nothing_moves(served: Served) -> None:
    with served.client() as c:
        start = commanded(c)
        for body, field in BAD_BODIES:
            doc = problem(c.post(JOG, json=body), 422, "invalid_request")
            assert field in doc["detail"], (body, doc)
        r = c.post(
            JOG,
            content=b'{"mode": "joint", "joint": 1, "delta_deg": NaN}',
            headers={"content-type": "application/json"},
        )
        assert r.status_code == 422, r.text
        assert commanded(c) == start


def test_a_jog_the_robot_refuses_moves_nothing_and_says_why(served: Served) -> None:
    """Toward the table from the reference pose (68 mm above it; the camera's front must stay 40 mm above):
    the keep-out refuses the step that would cross it, and the arm stays where it was."""
    with served.client() as c:
        start = commanded(c)
        for _ in range(3):
            r = c.post(JOG, json={"mode": "camera", "axis": "z", "delta": 10.0})
            if r.status_code != 200:
                break
        doc = problem(r, 422, "motion_rejected")
        assert "nothing" in doc["detail"] or "refused" in doc["detail"], doc
        before = commanded(c)
        assert before != start  # the allowed steps moved it
        assert c.post(JOG, json={"mode": "camera", "axis": "z", "delta": 10.0}).status_code == 422
        assert commanded(c) == before


def test_motion_from_another_machine_is_refused_and_nothing_moves(served: Served) -> None:
    remote = remote_client(served)
    with served.client() as c:
        start = commanded(c)
        for path, body in (
            (JOG, {"mode": "joint", "joint": 1, "delta_deg": 1.0}),
            *((p, None) for p in TEACH),
        ):
            doc = problem(remote.post(path, json=body), 403, "remote_motion")
            assert "--allow-remote-motion" in doc["detail"]
        assert commanded(c) == start

        # the safety panel's reading says so, to either client
        here = c.get("/api/v1/station/safety").json()
        there = remote.get("/api/v1/station/safety").json()
        assert here["keep_out_volumes"] == served.service.in_worker(fixture_count) > 0
        assert here["max_speed_pct"] == 80.0  # the sim cell's cap
        assert here["latched"] is None
        assert here["local_acknowledgement"] is True
        assert (here["remote_motion"], here["local"], here["motion"]) == (False, True, True)
        assert (there["remote_motion"], there["local"], there["motion"]) == (False, False, False)
        served.app.state.access = dataclasses.replace(served.app.state.access, remote_motion=True)
        there = remote.get("/api/v1/station/safety").json()
        assert (there["remote_motion"], there["local"], there["motion"]) == (True, False, True)
        r = remote.post(JOG, json={"mode": "joint", "joint": 1, "delta_deg": 0.5})
        assert r.status_code == 200, r.text


def test_a_cookie_request_from_another_page_is_refused(served: Served) -> None:
    with httpx.Client(base_url=served.base, cookies={"station_token": TOKEN}) as c:
        r = c.post(
            JOG, json={"mode": "joint", "joint": 1, "delta_deg": 1.0}, headers={"origin": "http://evil.test"}
        )
        problem(r, 403, "cross_origin")
    with httpx.Client(base_url=served.base) as c:
        problem(c.post(JOG, json={"mode": "joint", "joint": 1, "delta_deg": 1.0}), 401, "token_required")


def test_a_latched_stop_refuses_jog_and_teach_until_acknowledged_at_the_station(served: Served) -> None:
    with served.client() as c:
        start = commanded(c)
        served.service.in_worker(latch)
        for path, body in ((JOG, {"mode": "joint", "joint": 1, "delta_deg": 1.0}), (TEACH[0], None)):
            doc = problem(c.post(path, json=body), 409, "stop_latched")
            assert "acknowledge" in doc["detail"], doc
        assert commanded(c) == start
        assert remote_client(served).post("/api/v1/station/robot/acknowledge").status_code == 403
        acknowledge_stop(c)
        r = c.post(JOG, json={"mode": "joint", "joint": 1, "delta_deg": 1.0})
        assert r.status_code == 200, r.text


def test_jog_and_teach_are_refused_while_a_session_owns_the_arm(served: Served) -> None:
    with served.client() as c:
        r = c.post("/api/v1/sessions", json=REPEATABILITY)
        assert r.status_code == 201, r.text
        sid = r.json()["id"]
        wait_state(c, sid, {"running"})
        for path, body in (
            (JOG, {"mode": "joint", "joint": 1, "delta_deg": 1.0}),
            *((p, None) for p in TEACH),
        ):
            doc = problem(c.post(path, json=body), 409, "conflict")
            assert sid in doc["detail"], doc
            assert "abort" in doc["detail"], doc
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, sid)["state"] == "aborted"
        acknowledge_stop(c)


def test_teaching_without_a_configuration_file_says_how_to_start_the_service(served: Served) -> None:
    with served.client() as c:
        start = commanded(c)
        for path in TEACH:
            doc = problem(c.post(path), 409, "not_available")
            assert "--config" in doc["detail"], doc
        problem(c.post("/api/v1/station/teach/artifact/a%20b"), 422, "invalid_request")
        assert commanded(c) == start


# ------------------------------------------------------------------ teach, with a configuration file


def table_only_config(path: Path, **options: Any) -> str:
    """A lab's file at ``path`` with the table's artifact only, as drawn (its text returned)."""
    text = lab_config(
        reference=[0.0, 30.0, 60.0, 0.0, 90.0, 0.0],
        artifacts=[[482.0, 0.0, 330.0]],
        normals=[[0.0, 0.0, 1.0]],
        turns=[0.0],
        names=["table"],
        **options,
    )
    path.write_text(text, encoding="utf-8")
    return text


def test_teaching_the_sensor_mount_and_the_reference_rewrites_the_file_with_its_comments(
    tmp_path: Path,
) -> None:
    path = tmp_path / "station.toml"
    text = table_only_config(path, sensor_z=2.0)
    with served_with_config(path, tmp_path / "data", seed=3) as served, served.client() as c:
        # the keep-out carries the head where the file's mount puts it: 120 (camera) + 2 - 70 (its body)
        assert served.service.in_worker(sensor_head_z) == pytest.approx(52.0, abs=1e-9)
        r = c.post("/api/v1/station/teach/sensor-mount")
        assert r.status_code == 200, r.text
        doc = r.json()
        # and where the taught one does, from now on
        taught_head = 120.0 + doc["taught"]["translation_z_mm"] - 70.0
        assert served.service.in_worker(sensor_head_z) == pytest.approx(taught_head, abs=1e-3)  # as written
        assert doc["what"] == "sensor-mount"
        assert doc["config"] == "station.toml"
        assert doc["taught"]["translation_z_mm"] == pytest.approx(0.0, abs=0.1)  # the sim's true mount
        assert (tmp_path / doc["backup"]).read_text(encoding="utf-8") == text
        written = path.read_text(encoding="utf-8")
        assert "# from the bracket's drawing" in written
        assert "keep this comment" in written
        config = load_config(path)
        assert config.distance_sensor is not None
        assert config.distance_sensor.mount.translation_mm[2] == pytest.approx(
            doc["taught"]["translation_z_mm"], abs=1e-3
        )

        # the operator jogged 0.6 mm off the crossing: teaching the reference brings it back on
        assert c.post(JOG, json={"mode": "camera", "axis": "x", "delta": 0.6}).status_code == 200
        r = c.post("/api/v1/station/teach/reference")
        assert r.status_code == 200, r.text
        doc = r.json()
        np.testing.assert_allclose(doc["taught"]["reference_joints_deg"], REFERENCE_JOINTS_DEG, atol=0.05)
        config = load_config(path)
        assert config.robot is not None
        assert config.distance_sensor is not None
        np.testing.assert_allclose(
            config.robot.reference_joints_deg, doc["taught"]["reference_joints_deg"], atol=1e-3
        )
        assert len(list(tmp_path.glob("station.toml.*.bak"))) == 2  # no backup overwritten
        # the worker uses the taught pose at once, and /station shows the taught values
        r = c.get("/api/v1/station/robot")
        assert r.json()["at_reference"] is True, r.text
        shown = c.get("/api/v1/station").json()["config"]
        np.testing.assert_allclose(
            shown["robot"]["reference_joints_deg"], doc["taught"]["reference_joints_deg"], atol=1e-3
        )
        assert shown["distance_sensor"]["mount"]["translation_mm"][2] == pytest.approx(
            config.distance_sensor.mount.translation_mm[2], abs=1e-3
        )


def test_teaching_through_a_calibration_session_that_is_not_one_is_refused_and_nothing_moves(
    tmp_path: Path,
) -> None:
    path = tmp_path / "station.toml"
    text = table_only_config(path)
    with served_with_config(path, tmp_path / "data", seed=3) as served, served.client() as c:
        start = commanded(c)
        for what in TEACH:
            doc = problem(
                c.post(what, json={"calibration_session": "abcd1234"}), 422, "calibration_session_invalid"
            )
            assert "station run calibration" in doc["detail"], doc
        problem(c.post(TEACH[1], json={"calibration_session": "not an id"}), 422, "invalid_request")
        problem(c.post(TEACH[1], json={"calibration": "abcd1234"}), 422, "invalid_request")
        assert commanded(c) == start
        assert path.read_text(encoding="utf-8") == text  # nothing written
