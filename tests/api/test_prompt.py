"""Operator prompts through the API with --manual-prompts: a person confirms each micrometer setting, the
simulated world's micrometers follow what they confirm, and the validation measures the real moves."""

from __future__ import annotations

import time
from typing import Any

import httpx

from station.worker import SessionHost
from tests.api.conftest import ServeFactory, wait_final

# three positions (um, table axes): a small same-direction validation
PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0]]
VALIDATION = {"kind": "validation", "params": {"pattern_um": PATTERN}}


def next_prompt(c: httpx.Client, seen: set[str]) -> dict[str, Any] | None:
    """The next open prompt not yet seen (None once the session has ended)."""
    while True:
        r = c.get("/api/v1/prompt")
        if r.status_code == 200 and r.json()["id"] not in seen:
            return dict(r.json())
        sessions = c.get("/api/v1/sessions").json()["items"]
        if sessions and sessions[0]["state"] in {"succeeded", "failed", "aborted", "stopped"}:
            return None
        time.sleep(0.02)


def put_on_table(c: httpx.Client, sid: str, seen: set[str], content: str = "cross") -> None:
    """Answer the session's first prompt: what to put on the X-Y table (the station knows nothing yet)."""
    p = next_prompt(c, seen)
    assert p is not None
    seen.add(p["id"])
    assert p["kind"] == "table_content"
    assert p["fields"] == []
    assert p["details"]["content"] == content
    assert p["details"]["was"] == "unknown"
    assert c.get(f"/api/v1/sessions/{sid}").json()["state"] == "awaiting_operator"
    ok = c.post(f"/api/v1/prompt/{p['id']}/confirm", json={})
    assert ok.status_code == 200, ok.text


def table_content(host: SessionHost) -> str:
    """What lies on the simulated world's X-Y table (in the station's worker process)."""
    return str(host.devices.truth.world.table_content)


def table_readings_mm(host: SessionHost) -> tuple[float, float]:
    """The simulated world's micrometer readings (in the station's worker process)."""
    x_mm, y_mm = host.devices.truth.world.table_readings_mm()
    return float(x_mm), float(y_mm)


def readings_followed(host: SessionHost) -> int:
    """How many confirmed readings the sim's listener moved the world's micrometers to."""
    followed: int = host.devices.truth.follower.followed
    return followed


def test_a_person_answers_every_prompt_and_the_artifact_moves(make_served: ServeFactory) -> None:
    served = make_served(manual=True)
    with served.client() as c:
        assert c.get("/api/v1/prompt").status_code == 204
        sid = c.post("/api/v1/sessions", json=VALIDATION).json()["id"]
        seen: set[str] = set()
        put_on_table(c, sid, seen)
        answered = 0
        said: list[tuple[int, int, str]] = []
        while (p := next_prompt(c, seen)) is not None:
            seen.add(p["id"])
            said.append((int(p["details"]["position"]), int(p["details"]["positions"]), p["details"]["move"]))
            fields = {f["name"]: f for f in p["fields"]}
            assert set(fields) == {"x_in", "y_in"}
            assert fields["x_in"]["unit"] == "in"
            assert c.get(f"/api/v1/sessions/{sid}").json()["state"] == "awaiting_operator"
            # readings this prompt does not take are refused and the prompt stays open
            bad = c.post(f"/api/v1/prompt/{p['id']}/confirm", json={"readings": {"z_in": 1.0}})
            assert bad.status_code == 422
            assert "x_in" in bad.json()["detail"]
            readings = {n: f["requested"] for n, f in fields.items()}
            ok = c.post(f"/api/v1/prompt/{p['id']}/confirm", json={"readings": readings})
            assert ok.status_code == 200, ok.text
            assert ok.json()["outcome"] == "confirmed"
            # the world's micrometers now read what the person confirmed
            x_mm, y_mm = served.service.in_worker(table_readings_mm)
            assert abs(x_mm - (readings["x_in"] - 0.5) * 25.4) < 1e-9
            assert abs(y_mm - (readings["y_in"] - 0.5) * 25.4) < 1e-9
            stale = c.post(f"/api/v1/prompt/{p['id']}/confirm", json={})
            assert stale.status_code == 409
            assert stale.json()["code"] == "prompt_not_open"
            answered += 1
        final = wait_final(c, sid)
    assert final["state"] == "succeeded", final["error"]
    assert answered >= len(PATTERN)
    # each prompt says which position of how many, and whether it is the overshoot before a backwards
    # move (same-direction approach: before the first position and before the move back in -x)
    assert said == [
        (1, 4, "overshoot"),
        (1, 4, "position"),
        (2, 4, "position"),
        (3, 4, "position"),
        (4, 4, "overshoot"),
        (4, 4, "position"),
    ]
    assert served.service.in_worker(readings_followed) == answered
    assert len(final["results"]["positions"]) == len(PATTERN)
    # the measured displacements follow the confirmed moves (um): the artifact really moved
    for pos in final["results"]["positions"]:
        assert abs(pos["measured_um"][0] - pos["commanded_um"][0]) < 30, pos


def test_cancelling_the_prompt_ends_the_session(make_served: ServeFactory) -> None:
    served = make_served(manual=True)
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=VALIDATION).json()["id"]
        seen: set[str] = set()
        put_on_table(c, sid, seen)
        p = next_prompt(c, seen)
        assert p is not None
        assert p["kind"] == "table.move"
        r = c.post(f"/api/v1/prompt/{p['id']}/cancel", json={"reason": "cannot reach the table"})
        assert r.status_code == 200
        assert r.json()["outcome"] == "cancelled"
        final = wait_final(c, sid)
    assert final["state"] == "failed"
    assert "cancelled" in final["error"]


def test_abort_cancels_the_open_prompt(make_served: ServeFactory) -> None:
    served = make_served(manual=True)
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=VALIDATION).json()["id"]
        assert next_prompt(c, set()) is not None
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, sid)["state"] == "aborted"
        assert c.get("/api/v1/prompt").status_code == 204


def test_declining_what_to_put_on_the_table_ends_the_session_with_what_to_do(
    make_served: ServeFactory,
) -> None:
    served = make_served(manual=True)
    ruler = {"kind": "validation", "params": {"artifact": "ruler", "pattern_um": PATTERN}}
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=ruler).json()["id"]
        p = next_prompt(c, set())
        assert p is not None
        assert p["kind"] == "table_content"
        assert p["message"].startswith("Put the ruler on the X-Y table")
        r = c.post(f"/api/v1/prompt/{p['id']}/cancel", json={"reason": "no ruler at hand"})
        assert r.status_code == 200
        final = wait_final(c, sid)
    assert final["state"] == "failed"
    assert "the operator declined to put the ruler on the X-Y table (no ruler at hand)" in final["error"]
    assert "put the ruler on the X-Y table, then start the session again" in final["error"]
    assert served.service.in_worker(table_content) == "cross"  # nothing was put there
    types = [e.type for e in served.service.record.events(sid, limit=10_000)]
    assert "preflight" not in types
    assert "table_content" not in types
    assert served.service.record.captures(sid) == []
