"""The service's sessions run in the station's worker process (``station.worker``): the runner and the
devices are there, the HTTP side here; what crosses between them keeps its meaning (exception types,
log records, events), and a worker that dies or is terminated leaves the session ``interrupted``."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import time

import pytest

from station.record import SessionLockError
from station.worker import SessionHost
from station.worker._transport import _pack_exception, _unpack_exception
from tests.api.conftest import Served, wait_final, wait_state

LONG = {"kind": "repeatability", "params": {"cycles": 5000, "joints": [1], "warmup_cycles": 0}}
SHORT = {"kind": "repeatability", "params": {"cycles": 2, "joints": [1], "warmup_cycles": 0}}


def process_id(host: SessionHost) -> int:
    return os.getpid()


def lock_pid(host: SessionHost) -> int | None:
    from station.record import lock_holder

    holder = lock_holder(host.record.data_dir)
    return None if holder is None else int(holder["pid"])


def test_the_session_runs_in_the_worker_process(served: Served, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO)
    worker_pid = served.service.in_worker(process_id)
    assert worker_pid == served.service.worker.pid != os.getpid()
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=LONG).json()["id"]
        wait_state(c, sid, {"running"})
        # the station lock (held while a session runs) is the worker's
        assert served.service.in_worker(lock_pid) == worker_pid
        worker = c.get("/api/v1/station").json()["worker"]
        assert worker["alive"] is True
        assert worker["pid"] == worker_pid
        # preferred to the HTTP side when the machine allows it (root, CAP_SYS_NICE); else as the HTTP side
        allowed = (
            subprocess.run([sys.executable, "-c", "import os; os.setpriority(0, 0, -10)"]).returncode == 0
        )
        assert worker["nice"] == (-10 if allowed else os.getpriority(os.PRIO_PROCESS, 0))
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, sid)["state"] == "aborted"
    # the worker's log records come out of this process's loggers, marked as the worker's
    runner_logs = [r for r in caplog.records if r.name == "station.runner"]
    assert runner_logs, [r.name for r in caplog.records]
    assert all(r.processName == "station-worker" for r in runner_logs)


def test_exceptions_keep_their_type_and_attributes_across_the_pipe() -> None:
    exc = SessionLockError("/data/station.lock", {"pid": 12, "host": "bench", "session_id": "abc"})
    back = _unpack_exception(_pack_exception(exc))
    assert type(back) is SessionLockError
    assert str(back) == str(exc)
    assert vars(back) == vars(exc)


def test_a_dead_worker_leaves_the_session_interrupted_and_the_api_says_why(served: Served) -> None:
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=LONG).json()["id"]
        wait_state(c, sid, {"running"})
        os.kill(served.service.worker.pid, signal.SIGKILL)
        doc = wait_final(c, sid)
        assert doc["state"] == "interrupted"
        station = c.get("/api/v1/station").json()
        assert station["worker"]["alive"] is False
        assert station["session"] is None
        r = c.post("/api/v1/sessions", json=SHORT)
        assert r.status_code == 503
        assert r.json()["code"] == "worker_unavailable"
        assert "restart the service" in r.json()["detail"]
        assert c.get("/api/v1/health").status_code == 200


def test_a_terminated_worker_stops_and_records_its_session(served: Served) -> None:
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json=LONG).json()["id"]
        wait_state(c, sid, {"running"})
        os.kill(served.service.worker.pid, signal.SIGTERM)
        doc = wait_final(c, sid)
        assert doc["state"] == "interrupted"
        assert "terminated" in doc["error"]
        while served.service.worker.alive:
            time.sleep(0.02)
        # the runner's abort (the robot's latched stop) ran before the session was recorded interrupted
        states = [
            e.data["state"] for e in served.service.record.events(sid, limit=10_000) if e.type == "state"
        ]
        assert states[-1] == "interrupted", states
        assert "aborting" in states, states
