"""Issue 23's last safety rule: motion from clients on other machines is refused unless the service runs
with ``--allow-remote-motion``; stopping is never refused (pause, stop, abort need the token only)."""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import pytest

from api import Access
from tests.api.conftest import Served, ServeFactory, acknowledge_stop, remote_client, wait_final

PARAMS: dict[str, Any] = {"cycles": 30, "joints": [1], "warmup_cycles": 0}
REPEATABILITY: dict[str, Any] = {"kind": "repeatability", "params": PARAMS}


@pytest.mark.timeout(180)
def test_a_remote_client_may_stop_the_arm_but_not_move_it_unless_allowed(served: Served) -> None:
    remote = remote_client(served)
    access = remote.get("/api/v1/access").json()
    assert access["authenticated"] is True
    assert access["local"] is False
    assert access["motion"] is False
    with served.client() as c:
        assert c.get("/api/v1/access").json()["motion"] is True
        total = c.get("/api/v1/sessions").json()["total"]

        # a session that moves the arm, and the route to the reference pose: refused, nothing created
        for path, body in (("/api/v1/sessions", REPEATABILITY), ("/api/v1/station/robot/to-reference", None)):
            r = remote.post(path, json=body)
            assert r.status_code == 403, (path, r.text)
            assert r.json()["code"] == "remote_motion"
            assert "--allow-remote-motion" in r.json()["detail"]
        assert c.get("/api/v1/sessions").json()["total"] == total
        # an offline kind drives nothing: not refused as motion (here refused for its missing source)
        r = remote.post("/api/v1/sessions", json={"kind": "reanalyse", "params": {}})
        assert r.status_code != 403, r.text

        # started at the station, a remote client can pause and abort it, but not resume it
        r = c.post("/api/v1/sessions", json=REPEATABILITY)
        assert r.status_code == 201, r.text
        sid = r.json()["id"]
        while not any(s.name == "J1 cycle 2" for s in served.service.record.steps(sid)):
            time.sleep(0.02)
        assert remote.post(f"/api/v1/sessions/{sid}/actions", json={"action": "pause"}).status_code == 201
        r = remote.post(f"/api/v1/sessions/{sid}/actions", json={"action": "resume"})
        assert r.status_code == 403, r.text
        assert r.json()["code"] == "remote_motion"
        assert remote.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, sid)["state"] == "aborted"
        acknowledge_stop(c)

        # with --allow-remote-motion (the service's access as station serve builds it) it may
        served.app.state.access = dataclasses.replace(served.app.state.access, remote_motion=True)
        assert isinstance(served.app.state.access, Access)
        assert remote.get("/api/v1/access").json()["motion"] is True
        r = remote.post(f"/api/v1/sessions/{sid}/actions", json={"action": "resume"})
        assert r.status_code == 201, r.text
        assert remote.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, sid)["state"] == "aborted"
        # the stop it latched is still released only at the station
        assert remote.post("/api/v1/station/robot/acknowledge").status_code == 403
        acknowledge_stop(c)


def test_a_plan_above_the_cells_speed_cap_is_refused_at_pre_flight(make_served: ServeFactory) -> None:
    """Repeatability's default speed is 80 %; under a 50 % cap pre-flight refuses it, naming the cap and
    where it is set, before anything moves; at 50 % it runs."""
    served = make_served(max_speed_pct=50.0)
    with served.client() as c:
        r = c.post("/api/v1/sessions", json={**REPEATABILITY, "params": {**PARAMS, "cycles": 3}})
        assert r.status_code == 422, r.text
        assert r.json()["code"] == "preflight_failed"
        problem = " ".join(r.json()["problems"])
        assert "80" in problem
        assert "50" in problem
        assert "max_speed_pct" in problem
        assert served.service.in_worker(motions) == 0  # nothing moved
        r = c.post(
            "/api/v1/sessions", json={**REPEATABILITY, "params": {**PARAMS, "cycles": 3, "speed_pct": 50}}
        )
        assert r.status_code == 201, r.text
        done = wait_final(c, r.json()["id"])
        assert done["state"] == "succeeded", done["error"]


def motions(host: Any) -> int:
    """The controller twin's motions so far (in the station's worker)."""
    return len(host.devices.truth.twin.motion_log)
