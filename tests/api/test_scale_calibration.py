"""``/api/v1/station/scale-calibration``: the calibration a validation that passed its checks wrote, the
history, the revert (a mutation: token; 409 while a session runs or with nothing to revert to)."""

from __future__ import annotations

from typing import Any

from station import scale_calibration as scal
from tests.api.conftest import Served, wait_final, wait_state

ROUTE = "/api/v1/station/scale-calibration"
VALIDATION = {"kind": "validation", "params": {}}
LONG = {"kind": "repeatability", "params": {"cycles": 5000, "joints": [1], "warmup_cycles": 0}}


def validate(served: Served) -> dict[str, Any]:
    with served.client() as client:
        r = client.post("/api/v1/sessions", json=VALIDATION)
        assert r.status_code == 201, r.text
        final = wait_final(client, r.json()["id"])
    assert final["state"] == "succeeded", final["error"]
    return final


def test_validations_write_it_sessions_record_it_and_the_revert_goes_back(served: Served) -> None:
    with served.client() as c, served.client(token=False) as anonymous:
        assert c.get(ROUTE).json()["calibration"] is None
        first = validate(served)
        doc = c.get(ROUTE).json()
        assert doc["calibration"]["session_id"] == first["id"]
        assert doc["calibration"]["version"] == 1
        names = {ch["name"] for ch in doc["calibration"]["checks"]}
        assert {"table_moves", "groove_width", "rigid_mean", "rigid_max"} <= names
        assert all(ch["passed"] for ch in doc["calibration"]["checks"] if ch["severity"] == "fail")
        assert doc["entry"]["action"] == "validation"

        second = validate(served)  # measured with the first's calibration, which it records
        used = second["params"]["scale_calibration"]
        assert (used["session_id"], used["version"]) == (first["id"], 1)
        assert c.get(ROUTE).json()["calibration"]["session_id"] == second["id"]
        history = c.get(f"{ROUTE}/history").json()["items"]
        assert [(e["version"], e["calibration"]["session_id"]) for e in history] == [
            (2, second["id"]),
            (1, first["id"]),
        ]

        assert anonymous.post(f"{ROUTE}/revert").status_code == 401
        r = c.post(f"{ROUTE}/revert")
        assert r.status_code == 200, r.text
        back = r.json()
        assert (back["entry"]["action"], back["entry"]["restores"]) == ("revert", 1)
        assert back["calibration"]["session_id"] == first["id"]
        assert back["calibration"]["version"] == 3
        assert c.post(f"{ROUTE}/revert").json()["calibration"] is None  # before the first: none
        r = c.post(f"{ROUTE}/revert")
        assert r.status_code == 409
        assert r.json()["code"] == "nothing_to_revert"
        assert "station run validation" in r.json()["detail"]
        assert len(c.get(f"{ROUTE}/history").json()["items"]) == 4  # nothing lost


def test_the_revert_is_refused_while_a_session_runs(served: Served) -> None:
    data = served.service.record.data_dir
    # widths the sim's artifact (0.79375 mm) can have: the session's pre-flight scale check compares them
    # with the grooves the camera sees (station.scale_preflight) and refuses a session beyond 0.2 %
    for width, sid in ((0.7930, "aaaa1111"), (0.7937, "bbbb2222")):
        scal.write(data, scal.ScaleCalibration(groove_width_mm=width, u_mm=0.0004, session_id=sid))
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=LONG).json()["id"]
        wait_state(c, sid, {"running"})
        r = c.post(f"{ROUTE}/revert")
        assert r.status_code == 409
        assert f"session {sid} is running" in r.json()["detail"]
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        wait_final(c, sid)
    assert scal.load(scal.station_file(data)).session_id == "bbbb2222"  # unchanged
