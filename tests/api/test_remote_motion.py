"""Issue 23's last safety rule: motion from clients on other machines is refused unless the service runs
with ``--allow-remote-motion``; stopping is never refused (pause, stop, abort need the token only)."""

from __future__ import annotations

import dataclasses
import time

import pytest

from api import Access
from tests.api.conftest import Served, acknowledge_stop, remote_client, wait_final

REPEATABILITY = {"kind": "repeatability", "params": {"cycles": 30, "joints": [1], "warmup_cycles": 0}}


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
