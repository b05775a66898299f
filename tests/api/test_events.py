"""Server-Sent Events: a session's stream (id = its sequence number) and the station's (id = the
station-wide event id), resumed after Last-Event-ID; a client that leaves mid-stream harms nothing."""

from __future__ import annotations

import json
from typing import Any

import httpx

from tests.api.conftest import Served, wait_final

SHORT = {"kind": "repeatability", "params": {"cycles": 3, "joints": [1], "warmup_cycles": 0}}


def read_sse(response: httpx.Response, limit: int | None = None) -> list[dict[str, Any]]:
    """Parse an event stream into ``{"id", "event", "data"}`` dicts (comments and retry skipped)."""
    events: list[dict[str, Any]] = []
    current: dict[str, Any] = {}
    for line in response.iter_lines():
        if not line:
            if "data" in current:
                events.append(current)
                if limit is not None and len(events) >= limit:
                    return events
            current = {}
            continue
        field, _, value = line.partition(": ")
        if field == "data":
            current["data"] = json.loads(value)
        elif field in ("id", "event"):
            current[field] = value
    return events


def test_a_session_stream_carries_every_event_in_order_and_ends(served: Served) -> None:
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=SHORT).json()["id"]
        with c.stream("GET", f"/api/v1/sessions/{sid}/events") as r:
            assert r.status_code == 200
            assert r.headers["content-type"].startswith("text/event-stream")
            events = read_sse(r)
        final = wait_final(c, sid)
    ids = [int(e["id"]) for e in events]
    assert ids == list(range(1, len(ids) + 1))
    assert [e["data"]["seq"] for e in events] == ids
    assert events[-1]["event"] == "state"
    assert events[-1]["data"]["data"]["state"] == final["state"] == "succeeded"
    assert {"step_started", "image_captured", "measurement", "step_finished"} <= {e["event"] for e in events}


def test_a_session_stream_resumes_after_last_event_id(served: Served) -> None:
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=SHORT).json()["id"]
        wait_final(c, sid)
        with c.stream("GET", f"/api/v1/sessions/{sid}/events") as r:
            everything = read_sse(r)
        with c.stream("GET", f"/api/v1/sessions/{sid}/events", headers={"Last-Event-ID": "5"}) as r:
            rest = read_sse(r)
        bad = c.get(f"/api/v1/sessions/{sid}/events", headers={"Last-Event-ID": "five"})
    assert [e["id"] for e in rest] == [e["id"] for e in everything[5:]]
    assert bad.status_code == 422


def test_the_station_stream_resumes_by_station_wide_id(served: Served) -> None:
    with served.client() as c:
        first = c.post("/api/v1/sessions", json=SHORT).json()["id"]
        wait_final(c, first)
        second = c.post("/api/v1/sessions", json=SHORT).json()["id"]
        wait_final(c, second)
        total = len(served.service.record.events(None, limit=10_000))
        with c.stream("GET", "/api/v1/events") as r:
            everything = read_sse(r, limit=total)
        middle = everything[total // 2]["id"]
        with c.stream("GET", "/api/v1/events", headers={"Last-Event-ID": middle}) as r:
            rest = read_sse(r, limit=total - total // 2 - 1)
    ids = [int(e["id"]) for e in everything]
    assert ids == sorted(ids)
    assert {e["data"]["session_id"] for e in everything} == {first, second}
    assert [e["id"] for e in rest] == [e["id"] for e in everything[total // 2 + 1 :]]


def test_a_client_vanishing_mid_stream_harms_nothing(served: Served) -> None:
    long = {"kind": "repeatability", "params": {"cycles": 30, "joints": [1], "warmup_cycles": 0}}
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=long).json()["id"]
        for _ in range(5):  # five clients that read a little and hang up
            with c.stream("GET", f"/api/v1/sessions/{sid}/events") as r:
                assert len(read_sse(r, limit=2)) == 2
            with c.stream("GET", "/api/v1/events") as r:
                assert len(read_sse(r, limit=1)) == 1
        assert wait_final(c, sid)["state"] == "succeeded"
        assert c.get("/api/v1/health").status_code == 200
