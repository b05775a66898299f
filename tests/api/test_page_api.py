"""What the operator page needs from the API (issue 20), without a browser: who the client is
(``/access``), the plans' parameter schemas (``/plans``), a favicon, the robot's state and pose from the
start, the live view's numbers, the real progress of ended sessions, a served report whose figure links
load, CSV tables for every kind that has one, and reports asked for by several clients at once."""

from __future__ import annotations

import json
import re
import threading
from urllib.parse import urljoin

import httpx

from tests.api.conftest import TOKEN, Served, ServeFactory, wait_final

PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0]]


def run(c: httpx.Client, kind: str, params: dict[str, object]) -> str:
    r = c.post("/api/v1/sessions", json={"kind": kind, "params": params})
    assert r.status_code == 201, r.text
    sid: str = r.json()["id"]
    assert wait_final(c, sid)["state"] == "succeeded"
    return sid


def test_access_says_whether_the_client_holds_the_token(make_served: ServeFactory) -> None:
    for open_reads in (True, False):
        served = make_served(public_read=open_reads)
        wrong = {"Authorization": "Bearer wrong-token-wrong-token"}
        with (
            served.client(token=False) as anonymous,
            served.client() as holder,
            served.client(token=False, cookies={"station_token": TOKEN}) as logged_in,
            served.client(token=False, headers=wrong) as mistaken,
        ):
            nobody = anonymous.get("/api/v1/access").json()
            here = {"local": True, "motion": True}
            assert nobody == {"authenticated": False, "open_reads": open_reads, **here}
            held = holder.get("/api/v1/access").json()
            assert held == {"authenticated": True, "open_reads": open_reads, **here}
            assert logged_in.get("/api/v1/access").json()["authenticated"] is True
            assert mistaken.get("/api/v1/access").json()["authenticated"] is False
        served.stop()


def test_plans_give_every_kind_its_schema_with_the_defaults(served: Served) -> None:
    with served.client() as c:
        kinds = c.get("/api/v1/station").json()["plans"]
        plans = {p["name"]: p for p in c.get("/api/v1/plans").json()["plans"]}
        icon = c.get("/favicon.ico")
    assert list(plans) == kinds
    assert "calibration" in kinds
    assert plans["calibration"]["needs"] == ["camera", "distance_sensor", "robot"]
    assert plans["sweep"]["needs"] == []
    props = {k: p["params_schema"]["properties"] for k, p in plans.items()}
    # defaults a factory computes are shown too
    assert props["repeatability"]["joints"]["default"] == [1, 2, 3, 4, 5, 6]
    assert props["calibration"]["turns_deg"]["default"] == [-20.0, 70.0, 160.0, 250.0]
    assert props["repeatability"]["cycles"] == {
        **props["repeatability"]["cycles"],
        "default": 30,
        "minimum": 2,
    }
    # one stored session or an archive selection: exactly one of the three (the model's own check)
    assert "required" not in plans["sweep"]["params_schema"]
    assert {"session", "sessions", "select"} <= set(plans["sweep"]["params_schema"]["properties"])
    assert icon.status_code == 200
    assert icon.headers["content-type"] == "image/svg+xml"
    assert icon.content.startswith(b"<svg")


def test_the_robot_is_read_from_the_start_and_the_live_view_carries_its_numbers(served: Served) -> None:
    with served.client() as c:
        while (robot := c.get("/api/v1/station").json()["robot"])["state"] == "reading":
            pass
        snapshot = c.get("/api/v1/camera/snapshot.png", params={"overlay": "true"})
    assert robot["state"] == "idle", robot
    assert robot["power"] is True
    assert robot["homed"] is True
    assert robot["commanded_joints_deg"] == robot["reference_joints_deg"] == [0.0, 30.0, 60.0, 0.0, 90.0, 0.0]
    assert robot["at_reference"] is True
    assert robot["error"] is None
    assert snapshot.status_code == 200
    numbers = json.loads(snapshot.headers["X-Measurement"])
    assert numbers["ok"] is True
    assert set(numbers) == {"ok", "center_px", "center_mm"}
    assert 0 < numbers["center_px"][0] < 640


def test_ended_sessions_show_their_progress_reports_and_tables(served: Served) -> None:
    with served.client() as c:
        validation = run(c, "validation", {"pattern_um": PATTERN})
        sweep = run(c, "sweep", {"session": validation, "grid": {"testwidth": [3, 5]}})
        again = run(c, "reanalyse", {"session": validation})
        # the validation is no longer the worker's latest session: its progress comes from the record
        assert c.get(f"/api/v1/sessions/{validation}").json()["progress"] == {
            "done": 4,
            "total": 4,
            "eta_s": None,
        }
        listed = {s["id"]: s["progress"] for s in c.get("/api/v1/sessions").json()["items"]}
        assert listed[sweep] == {"done": 2, "total": 2, "eta_s": None}

        # several clients asking for a new report at once all get it
        codes: list[int] = []

        def figures() -> None:
            with served.client() as own:
                codes.append(own.get(f"/api/v1/sessions/{sweep}/figures").status_code)

        threads = [threading.Thread(target=figures) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(60)
        assert codes == [200] * 4

        # the served report's figure links load from the API (they are relative to a <base>)
        page = c.get(f"/api/v1/sessions/{validation}/report.html")
        assert page.status_code == 200
        assert '<head><base href="figures/">' in page.text
        links = re.findall(r'<a href="([^"]+\.(?:png|svg))">', page.text)
        assert links
        base = urljoin(str(page.url), "figures/")
        for link in links:
            r = c.get(urljoin(base, link))
            assert r.status_code == 200, link

        # a CSV table for each kind that has one: the sweep's trials, the re-analysis's positions
        trials = c.get(f"/api/v1/sessions/{sweep}/results", params={"format": "csv"})
        assert trials.status_code == 200
        rows = trials.text.splitlines()
        assert rows[0].split(",")[:3] == ["trial", "number", "overrides.testwidth"]
        assert len(rows) == 1 + 2
        positions = c.get(f"/api/v1/sessions/{again}/results", params={"format": "csv"})
        assert positions.status_code == 200
        assert len(positions.text.splitlines()) == 1 + len(PATTERN)
