"""Issue 23's latch through the service: after an abort the robot's stop stays latched, every session that
moves the arm is refused at pre-flight and the route to the reference pose too, until a person at the
station acknowledges it; a client on another machine cannot, whatever token it holds."""

from __future__ import annotations

import time
from typing import Any

import pytest

from tests.api.conftest import Served, acknowledge_stop, remote_client, wait_final

PARAMS: dict[str, Any] = {"cycles": 3, "joints": [1], "warmup_cycles": 0}
REPEATABILITY: dict[str, Any] = {"kind": "repeatability", "params": PARAMS}


def latched(c: Any, *, expect: bool) -> str | None:
    """The robot's latch as ``/station`` shows it, once the service has read the arm again (its read
    after a session or an acknowledgement runs in a thread of its own; a hang fails on the timeout)."""
    while True:
        robot = c.get("/api/v1/station").json()["robot"]
        if robot["state"] == "idle" and (robot["latched"] is not None) == expect:
            return robot["latched"]
        time.sleep(0.1)


@pytest.mark.timeout(180)
def test_an_aborted_session_latches_until_acknowledged_at_the_station_never_remotely(served: Served) -> None:
    with served.client() as c:
        r = c.post(
            "/api/v1/sessions", json={**REPEATABILITY, "params": {**REPEATABILITY["params"], "cycles": 30}}
        )
        assert r.status_code == 201, r.text
        sid = r.json()["id"]
        while not any(s.name == "J1 cycle 2" for s in served.service.record.steps(sid)):
            time.sleep(0.02)
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, sid)["state"] == "aborted"
        reason = latched(c, expect=True)
        assert reason is not None
        assert "stop()" in reason

        # a session that moves the arm: refused at pre-flight, saying how to acknowledge; nothing moved
        r = c.post("/api/v1/sessions", json=REPEATABILITY)
        assert r.status_code == 422, r.text
        assert r.json()["code"] == "preflight_failed"
        problem = " ".join(r.json()["problems"])
        assert "a stop is latched" in problem
        assert "acknowledge" in problem
        # the route to the reference pose: refused too (409: acknowledge first)
        r = c.post("/api/v1/station/robot/to-reference")
        assert r.status_code == 409, r.text
        assert r.json()["code"] == "stop_latched"

        # another machine holding the token cannot release it
        remote = remote_client(served)
        assert remote.get("/api/v1/access").json()["local"] is False
        r = remote.post("/api/v1/station/robot/acknowledge")
        assert r.status_code == 403, r.text
        assert r.json()["code"] == "remote_acknowledgement"
        assert "only from the station itself" in r.json()["detail"]
        assert latched(c, expect=True) == reason

        # the station itself (this loopback client) can; then the arm moves again
        assert c.get("/api/v1/access").json()["local"] is True
        assert acknowledge_stop(c)["reason"] == reason
        assert latched(c, expect=False) is None
        r = c.post("/api/v1/sessions", json=REPEATABILITY)
        assert r.status_code == 201, r.text
        done = wait_final(c, r.json()["id"])
        assert done["state"] == "succeeded", done["error"]
        # and a second acknowledgement finds nothing latched
        again = c.post("/api/v1/station/robot/acknowledge")
        assert again.status_code == 200
        assert again.json() == {"acknowledged": False, "reason": None}
