"""Sessions through the API: create and start, list, read, control, results; 409s and 4xx, nothing changed."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest

from station.cli import main
from station.resources import SessionOutcome, SessionResource, dumps
from station.worker import SessionHost
from tests.api.conftest import Served, wait_final, wait_state

SHORT = {"kind": "repeatability", "params": {"cycles": 3, "joints": [1], "warmup_cycles": 0}}
LONG = {"kind": "repeatability", "params": {"cycles": 5000, "joints": [1], "warmup_cycles": 0}}
STATES = {
    "idle", "running", "pausing", "paused", "awaiting_operator", "stopping", "stopped", "aborting", "aborted",
    "failed", "succeeded", "interrupted",
}  # fmt: skip


def test_a_session_is_created_started_and_listed(served: Served) -> None:
    with served.client() as c:
        r = c.post("/api/v1/sessions", json=SHORT)
        assert r.status_code == 201, r.text
        doc = r.json()
        assert {"id", "kind", "state", "progress", "results"} <= set(doc)
        assert doc["kind"] == "repeatability"
        assert doc["state"] in STATES
        assert set(doc["progress"]) == {"done", "total", "eta_s"}
        final = wait_final(c, doc["id"])
        assert final["state"] == "succeeded"
        assert final["progress"]["done"] == final["progress"]["total"] > 0
        listed = c.get("/api/v1/sessions", params={"limit": 10, "offset": 0}).json()
        assert listed["total"] == 1
        assert [i["id"] for i in listed["items"]] == [doc["id"]]
        assert c.get("/api/v1/sessions", params={"offset": 1}).json() == {"items": [], "total": 1}


def test_results_are_the_run_json_object_and_a_per_cycle_table(served: Served) -> None:
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=SHORT).json()["id"]
        wait_final(c, sid)
        res = c.get(f"/api/v1/sessions/{sid}/results").json()
        assert set(res) == {"id", "kind", "state", "results", "error"}
        assert res["results"]["n_cycles"] == 3
        assert res["results"]["rp_mm"]["J1"] > 0
        table = c.get(f"/api/v1/sessions/{sid}/results", params={"format": "csv"})
        assert table.headers["content-type"].startswith("text/csv")
        rows = list(csv.DictReader(io.StringIO(table.text)))
        assert [r["cycle"] for r in rows] == ["0", "1", "2"]
        assert {r["test"] for r in rows} == {"J1"}
        points = res["results"]["tests"]["J1"]["points_mm"]
        assert [float(r["x_mm"]) for r in rows] == [p[0] for p in points]


def test_a_second_running_session_is_refused_with_the_reason(served: Served) -> None:
    with served.client() as c:
        first = c.post("/api/v1/sessions", json=LONG).json()["id"]
        r = c.post("/api/v1/sessions", json=SHORT)
        assert r.status_code == 409
        assert r.json()["code"] == "conflict"
        assert first in r.json()["detail"]
        assert c.get("/api/v1/sessions").json()["total"] == 1
        assert c.post(f"/api/v1/sessions/{first}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, first)["state"] == "aborted"


def test_pause_resume_stop(served: Served) -> None:
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=LONG).json()["id"]
        wait_state(c, sid, {"running"})
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "pause"}).status_code == 201
        paused = wait_state(c, sid, {"paused"})
        assert paused["progress"]["done"] < paused["progress"]["total"]
        assert c.get("/api/v1/station").json()["session"]["state"] == "paused"
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "resume"}).status_code == 201
        wait_state(c, sid, {"running"})
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "stop"}).status_code == 201
        assert wait_final(c, sid)["state"] == "stopped"


def test_an_action_the_state_does_not_allow_is_a_409(served: Served) -> None:
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=SHORT).json()["id"]
        wait_final(c, sid)
        for action in ("pause", "resume", "stop", "abort"):
            r = c.post(f"/api/v1/sessions/{sid}/actions", json={"action": action})
            assert r.status_code == 409, (action, r.text)
            assert "succeeded" in r.json()["detail"]


def test_bad_requests_are_4xx_with_a_clear_message_and_nothing_changes(served: Served) -> None:
    with served.client() as c:
        r = c.post("/api/v1/sessions", json={"kind": "calibrate-everything"})
        assert r.status_code == 422
        assert "validation" in r.json()["detail"]  # names the kinds it knows
        r = c.post("/api/v1/sessions", json={"kind": "repeatability", "params": {"cycles": 1}})
        assert r.status_code == 422
        assert "cycles" in r.json()["detail"]
        r = c.post("/api/v1/sessions", json={"kind": "repeatability", "params": {"delta_deg": 500}})
        assert r.status_code == 422
        assert "delta_deg" in r.json()["detail"]
        r = c.post("/api/v1/sessions", json={"kind": "repeatability", "set": {"TESTWIDTH": -3}})
        assert r.status_code == 422
        r = c.post("/api/v1/sessions", content=b"{not json", headers={"content-type": "application/json"})
        assert r.status_code == 422
        r = c.post("/api/v1/sessions/abcdef123456/actions", json={"action": "explode"})
        assert r.status_code == 422
        assert c.get("/api/v1/sessions").json()["total"] == 0


def test_an_unknown_session_is_a_404_problem(served: Served) -> None:
    with served.client() as c:
        r = c.get("/api/v1/sessions/abcdef123456")
        assert r.status_code == 404
        assert r.headers["content-type"] == "application/problem+json"
        body = r.json()
        assert body["status"] == 404
        assert body["code"] == "session_not_found"
        assert c.get("/api/v1/no-such-thing").status_code == 404


def test_figures_report_and_export_import(served: Served) -> None:
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=SHORT).json()["id"]
        wait_final(c, sid)
        names = c.get(f"/api/v1/sessions/{sid}/figures").json()["figures"]
        assert any(n.endswith(".png") for n in names)
        assert any(n.endswith(".svg") for n in names)
        png = c.get(f"/api/v1/sessions/{sid}/figures/{next(n for n in names if n.endswith('.png'))}")
        assert png.status_code == 200
        assert png.content.startswith(b"\x89PNG")
        assert c.get(f"/api/v1/sessions/{sid}/figures/nothing.png").status_code == 404
        html = c.get(f"/api/v1/sessions/{sid}/report.html")
        assert html.status_code == 200
        assert "<html" in html.text.lower()
        latest = c.get(f"/api/v1/sessions/{sid}/latest.png")
        assert latest.content.startswith(b"\x89PNG")
        exported = c.get(f"/api/v1/sessions/{sid}/export.zip")
        assert exported.headers["content-type"] == "application/zip"
        dup = c.post(
            "/api/v1/sessions/import", content=exported.content, headers={"content-type": "application/zip"}
        )
        assert dup.status_code == 422  # the record has this session already
        bad = c.post(
            "/api/v1/sessions/import", content=b"PK not a zip", headers={"content-type": "application/zip"}
        )
        assert bad.status_code == 422
        assert bad.json()["code"] == "bad_archive"


def test_import_into_another_station(served: Served) -> None:
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=SHORT).json()["id"]
        wait_final(c, sid)
        archive = c.get(f"/api/v1/sessions/{sid}/export.zip").content
    from api import Access, ServiceSettings, StationService
    from tests.api.conftest import TOKEN, serve

    other = serve(
        StationService(ServiceSettings(data=served.service.record.data_dir.parent / "other")),
        Access(TOKEN, True),
    )
    try:
        with other.client() as c:
            r = c.post(
                "/api/v1/sessions/import", content=archive, headers={"content-type": "application/zip"}
            )
            assert r.status_code == 201, r.text
            assert r.json()["id"] == sid
            assert c.get(f"/api/v1/sessions/{sid}/results").json()["results"]["n_cycles"] == 3
    finally:
        other.stop()


def test_the_camera_snapshot_is_refused_while_a_session_owns_the_camera(served: Served) -> None:
    with served.client() as c:
        free = c.get("/api/v1/camera/snapshot.png", params={"overlay": True})
        assert free.status_code == 200
        assert free.content.startswith(b"\x89PNG")
        sid = c.post("/api/v1/sessions", json=LONG).json()["id"]
        wait_state(c, sid, {"running"})
        busy = c.get("/api/v1/camera/snapshot.png")
        assert busy.status_code == 409
        assert "latest.png" in busy.json()["detail"]
        c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"})
        wait_final(c, sid)


def arm_joints(host: SessionHost) -> list[float]:
    """The simulated arm's exact joint angles (in the station's worker process)."""
    return [float(v) for v in host.devices.truth.twin.arm.actual_exact()]


def test_out_of_limit_targets_are_refused_before_anything_moves(served: Served) -> None:
    before = served.service.in_worker(arm_joints)
    far = {"S1": [[0, 30, 60, 0, 90, 0], [75, 30, 60, 0, 90, 0]]}
    with served.client() as c:
        r = c.post(
            "/api/v1/sessions", json={"kind": "repeatability", "params": {"joints": [], "sequences": far}}
        )
        assert r.status_code == 422, r.text
        body = r.json()
        assert body["code"] == "preflight_failed"
        assert body["problems"]
        assert "nothing moved" in body["detail"]
        assert c.get("/api/v1/station").json()["session"] is None
    assert served.service.in_worker(arm_joints) == before


def test_the_cli_and_the_api_render_one_session_model(
    served: Served, data_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``station sessions --json`` lists the API's session resource without its live progress (one
    model, station.resources, two renderings); ``/results`` is ``station run --json``'s object."""
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=SHORT).json()["id"]
        wait_final(c, sid)
        resource = c.get(f"/api/v1/sessions/{sid}").json()
        results = c.get(f"/api/v1/sessions/{sid}/results").json()
    assert main(["sessions", "--json", "--data", str(data_dir)]) == 0
    (listed,) = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert set(resource) - set(listed) == {"progress"}
    assert listed == {k: v for k, v in resource.items() if k != "progress"}
    row = served.service.record.get_session(sid)
    assert json.loads(dumps(SessionOutcome.of(row))) == results
    assert SessionResource.model_validate(resource).id == sid  # the API's body is the model's


def test_a_calibration_session_runs_through_the_sessions_resource(served: Served) -> None:
    """The calibration plan through the API: created, pre-flighted, progressing; its bad parameters are
    a 422 naming the field; aborted from the API (the full session is tested in tests/sessions)."""
    with served.client() as c:
        bad = c.post("/api/v1/sessions", json={"kind": "calibration", "params": {"turns_deg": [45]}})
        assert bad.status_code == 422, bad.text
        assert "turns_deg" in bad.text
        r = c.post("/api/v1/sessions", json={"kind": "calibration", "params": {"turns_deg": [-20.0, 160.0]}})
        assert r.status_code == 201, r.text
        doc = r.json()
        assert doc["kind"] == "calibration"
        running = wait_state(c, doc["id"], {"running"})
        # 2 turns x the sim cell's 17 branches, and the steps along its three rulers (RulerPlan's 204
        # frames, one step for each position of each branch of a ruler: 41)
        assert running["progress"]["total"] == 2 * (1 + 4 * 4) + 41
        assert c.post(f"/api/v1/sessions/{doc['id']}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, doc["id"])["state"] == "aborted"
