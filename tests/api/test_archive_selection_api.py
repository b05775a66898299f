"""Issue 24, item 3, through the service: a sweep and a re-analysis of an archive selection are asked for
with the same parameters as ``station run`` (``sessions``, ``select``); a malformed selection is refused
when the session is asked for (422, naming the problem), a selection of sessions that cannot be read
fails the session before anything is measured, naming each."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.api.conftest import Served, wait_final

PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0]]


def run(c: httpx.Client, kind: str, params: dict[str, Any]) -> dict[str, Any]:
    r = c.post("/api/v1/sessions", json={"kind": kind, "params": params})
    assert r.status_code == 201, r.text
    return wait_final(c, r.json()["id"])


@pytest.mark.timeout(180)
def test_the_service_sweeps_and_reanalyses_an_archive_selection(served: Served) -> None:
    with served.client() as c:
        ids = [run(c, "validation", {"pattern_um": PATTERN})["id"] for _ in range(2)]
        sweep = run(c, "sweep", {"sessions": ids, "grid": {"skip": [1, 2]}})
        assert sweep["state"] == "succeeded", sweep["error"]
        results = sweep["results"]
        assert results["sessions"] == ids
        assert [[s["session"] for s in t["sessions"]] for t in results["trials"]] == [ids, ids]
        assert results["best"] in (1, 2)
        assert sweep["params"]["plan"]["sessions"] == ids

        again = run(c, "reanalyse", {"select": {"kind": "validation"}})
        assert again["state"] == "succeeded", again["error"]
        assert [s["source_session"] for s in again["results"]["sessions"]] == ids  # oldest first

        for params, says in (
            ({"session": ids[0], "select": {"kind": "validation"}}, "give exactly one of session, sessions"),
            ({"select": {"kind": "validation", "lab": "a"}}, "select.lab"),
        ):
            r = c.post("/api/v1/sessions", json={"kind": "sweep", "params": params})
            assert r.status_code == 422, r.text
            assert says in r.json()["detail"]

        refused = run(c, "sweep", {"sessions": [ids[0], sweep["id"]]})
        assert refused["state"] == "failed"
        assert f"session {sweep['id']} (sweep): it is a sweep session" in refused["error"]
        assert not (refused["results"] or {}).get("trials")  # no trial was run
