"""50 concurrent clients polling and streaming on loopback while a session runs: no error, and the
session ends as it would without them (a bounded version of ``python -m bench.service_load``)."""

from __future__ import annotations

import pytest

from bench.service_load import load
from tests.api.conftest import TOKEN, Served, wait_final


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_fifty_clients_while_a_session_runs(served: Served) -> None:
    with served.client() as c:
        sid = c.post(
            "/api/v1/sessions",
            json={"kind": "repeatability", "params": {"cycles": 20, "joints": [1], "warmup_cycles": 0}},
        ).json()["id"]
        stats = load(served.base, TOKEN, sid, clients=50, streamers=10, max_s=120, max_requests=20_000)
        final = wait_final(c, sid)
        summary = stats.summary()
        print(f"load: {summary}")
        assert stats.errors == []
        assert stats.requests > 50
        assert stats.events > 0
        assert final["state"] == "succeeded", final["error"]
        assert final["results"]["n_cycles"] == 20
        assert c.get("/api/v1/health").status_code == 200
