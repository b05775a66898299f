"""Ids in paths (issue 18, row 13): checked against their pattern at the route (404 otherwise), and the
record's canonical id in every header, whatever form of it the client gave."""

from __future__ import annotations

import pytest

from tests.api.conftest import Served, wait_final

SHORT = {"kind": "repeatability", "params": {"cycles": 2, "joints": [1], "warmup_cycles": 0}}
SUFFIXES = ("", "/results", "/figures", "/report.html", "/export.zip", "/latest.png", "/events")


@pytest.fixture
def sid(served: Served) -> str:
    with served.client() as c:
        created = c.post("/api/v1/sessions", json=SHORT)
        assert created.status_code == 201, created.text
        session_id: str = created.json()["id"]
        assert wait_final(c, session_id)["state"] == "succeeded"
    return session_id


def test_malformed_ids_are_404_at_the_route(served: Served, sid: str) -> None:
    """``<id>%0d%0a`` reached the Content-Disposition header ("Invalid HTTP header value", an empty
    reply); ``<id>%20`` gave ``filename="<id> .zip"``."""
    with served.client() as c:
        for bad in (f"{sid}%0d%0a", f"{sid}%20", f"{sid[:6]}%00", "zz" + sid[2:], sid + "0", "abc"):
            for suffix in SUFFIXES:
                r = c.get(f"/api/v1/sessions/{bad}{suffix}")
                assert r.status_code == 404, (bad, suffix, r.status_code, r.text[:200])
                assert r.headers["content-type"] == "application/problem+json"
                assert r.json()["code"] == "session_not_found"
            r = c.post(f"/api/v1/sessions/{bad}/actions", json={"action": "stop"})
            assert r.status_code == 404, (bad, r.text[:200])
        for bad in ("a%0d%0ab", "x y", "p" * 65):
            assert c.post(f"/api/v1/prompt/{bad}/confirm").status_code == 404
            assert c.post(f"/api/v1/prompt/{bad}/cancel").status_code == 404


def test_headers_carry_the_records_own_id(served: Served, sid: str) -> None:
    with served.client() as c:
        for given in (sid.upper(), sid[:8], sid[:8].upper()):
            r = c.get(f"/api/v1/sessions/{given}/export.zip")
            assert r.status_code == 200, r.text[:200]
            assert r.headers["content-disposition"] == f'attachment; filename="{sid}.zip"'
            assert c.get(f"/api/v1/sessions/{given}").json()["id"] == sid
