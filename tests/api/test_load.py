"""50 concurrent clients polling and streaming on loopback while a session runs: no error, and the
session ends as it would without them (a bounded version of ``python -m bench.service_load``, which
measures the runner's per-cycle overhead with and without the clients; no wall-clock verdict here).

What made the clients stall the runner is checked by count instead of by time: the runner's thread
calls one listener of the app per event however many streams are open (not one per client), and the
clients' polls of the running session are served from the service's cache (the record is read again
only after the session's state changes, not on every poll).
"""

from __future__ import annotations

import logging
from typing import Any

import pytest

from bench.service_load import load
from station.record import SessionRow
from tests.api.conftest import TOKEN, Served, wait_final


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_fifty_clients_while_a_session_runs(
    served: Served, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING)
    service = served.service
    subscriptions: list[Any] = []
    real_subscribe = service.reads.subscribe

    def counting_subscribe(listener: Any) -> Any:
        subscriptions.append(listener)
        return real_subscribe(listener)

    monkeypatch.setattr(service.reads, "subscribe", counting_subscribe)
    row_reads: list[str] = []
    real_get_session = service.record.get_session

    def counting_get_session(session_id: str) -> SessionRow:
        row_reads.append(session_id)
        return real_get_session(session_id)

    monkeypatch.setattr(service.record, "get_session", counting_get_session)
    with served.client() as c:
        sid = c.post(
            "/api/v1/sessions",
            json={"kind": "repeatability", "params": {"cycles": 20, "joints": [1], "warmup_cycles": 0}},
        ).json()["id"]
        reads_before = len(row_reads)
        stats = load(served.base, TOKEN, sid, clients=50, streamers=10, max_s=120, max_requests=20_000)
        final = wait_final(c, sid)
        summary = stats.summary()
        print(f"load: {summary}; subscriptions {len(subscriptions)}; row reads {len(row_reads)}")
        assert stats.errors == []
        # streamers hang up mid-stream now and then: a client leaving is no server error
        errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
        assert errors == [], [f"{r.name}: {r.getMessage()}" for r in errors[:3]]
        assert stats.requests > 50
        assert stats.events > 0
        assert final["state"] == "succeeded", final["error"]
        assert final["results"]["n_cycles"] == 20
        assert c.get("/api/v1/health").status_code == 200
        # one subscription to the runner's events for all ten streams and their reconnections
        assert len(subscriptions) == 1, subscriptions
        # the running session's row: read for each stream's connection (its cursor), after each state
        # change, and by each client once the session has ended -- not by every poll
        polls = stats.requests // 4  # the pollers cycle over four paths, this session's is one
        connections = 10 + stats.reconnects
        state_changes = sum(1 for e in service.record.events(sid, limit=10_000) if e.type == "state")
        reads = len(row_reads) - reads_before
        assert reads <= connections + state_changes + 50 + 10, (reads, polls, connections, state_changes)
        assert reads < polls, (reads, polls)
