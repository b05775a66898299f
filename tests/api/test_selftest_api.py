"""The controller self-test through the session API (issue 23, item 3): ``POST /api/v1/sessions`` with kind
``selftest`` runs it, ``/api/v1/station`` publishes the latest, and a later session carries it."""

from __future__ import annotations

import pytest

from tests.api.conftest import Served, wait_final

pytestmark = pytest.mark.timeout(300)

SELFTEST = {"kind": "selftest", "params": {"checks": ["directions", "world", "ready"]}}
SHORT = {"kind": "repeatability", "params": {"cycles": 2, "joints": [1], "warmup_cycles": 0}}


def test_the_station_publishes_the_latest_self_test_and_sessions_carry_it(served: Served) -> None:
    with served.client() as c:
        assert c.get("/api/v1/station").json()["selftest"] is None  # none yet
        r = c.post("/api/v1/sessions", json=SELFTEST)
        assert r.status_code == 201, r.text
        test = wait_final(c, r.json()["id"])
        assert test["state"] == "succeeded", test["error"]
        assert test["results"]["passed"] is True
        latest = c.get("/api/v1/station").json()["selftest"]
        assert latest["session_id"] == test["id"]
        assert latest["passed"] is True
        r = c.post("/api/v1/sessions", json=SHORT)
        assert r.status_code == 201, r.text
        later = wait_final(c, r.json()["id"])
        assert later["state"] == "succeeded", later["error"]
        assert later["results"]["selftest"] == latest
        (check,) = [k for k in later["results"]["checks"] if k["name"] == "selftest"]
        assert check["passed"] is True
