"""``station serve`` as a process: the generated token reaches stdout once and no log; Ctrl-C stops
the robot, records the session as interrupted and closes the devices; a restart resumes it through the API."""

from __future__ import annotations

import logging
import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import IO, Any

import httpx
import pytest

from tests.api.conftest import FINAL, Served, wait_final, wait_state

URL = re.compile(r"open (http://127\.0\.0\.1:\d+/)\?token=(\S+)")
LONG = {"kind": "repeatability", "params": {"cycles": 5000, "joints": [1], "warmup_cycles": 0}}


class ServeProcess:
    """``station -v -v serve --sim --port 0`` with stdout and stderr collected in threads."""

    def __init__(self, data: Path, *extra: str, env: dict[str, str] | None = None) -> None:
        environ = {k: v for k, v in os.environ.items() if k != "STATION_API_TOKEN"}
        environ.update(env or {})
        self.proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "station.cli",
                "-v",
                "-v",
                "serve",
                "--sim",
                "--port",
                "0",
                "--data",
                str(data),
                *extra,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=environ,
        )
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self._url = threading.Event()
        self.base = ""
        self.token = ""
        self._readers = [
            threading.Thread(target=self._read, args=(self.proc.stdout, self.stdout, True), daemon=True),
            threading.Thread(target=self._read, args=(self.proc.stderr, self.stderr, False), daemon=True),
        ]
        for t in self._readers:
            t.start()

    def _read(self, stream: IO[str], sink: list[str], find: bool) -> None:
        for line in stream:
            sink.append(line)
            if find and (m := URL.search(line)):
                self.base, self.token = m.group(1), m.group(2)
                self._url.set()
            elif find and "open http" in line and not self._url.is_set():
                self.base = line.split("open ", 1)[1].split()[0]
                self._url.set()

    def wait_url(self) -> None:
        while not self._url.wait(0.1):
            if self.proc.poll() is not None:
                raise AssertionError(f"station serve exited {self.proc.returncode}: {''.join(self.stderr)}")

    def client(self) -> httpx.Client:
        return httpx.Client(base_url=self.base, headers={"Authorization": f"Bearer {self.token}"}, timeout=30)

    def interrupt(self) -> int:
        self.proc.send_signal(signal.SIGINT)
        return self.finish()

    def finish(self) -> int:
        """Wait for the process to end, read what it wrote, close the pipes."""
        code = self.proc.wait(60)
        for t in self._readers:
            t.join(10)
        for stream in (self.proc.stdout, self.proc.stderr):
            if stream is not None:
                stream.close()
        return code


@pytest.mark.slow
def test_the_generated_token_is_printed_once_and_never_logged(tmp_path: Path) -> None:
    server = ServeProcess(tmp_path / "data")
    try:
        server.wait_url()
        assert len(server.token) >= 32
        with httpx.Client(base_url=server.base, timeout=30, follow_redirects=True) as browser:
            assert browser.get("/", params={"token": server.token}).status_code == 200  # login, redirect
            page = {"Origin": server.base.rstrip("/")}  # the page's own requests carry its origin
            assert browser.post("/api/v1/sessions", json={"kind": "nope"}, headers=page).status_code == 422
            assert browser.get("/?token=wrong-token-wrong").status_code == 401
        with server.client() as c:
            sid = c.post("/api/v1/sessions", json={**LONG, "params": {"cycles": 3, "joints": [1]}}).json()[
                "id"
            ]
            with c.stream("GET", f"/api/v1/sessions/{sid}/events") as r:
                assert sum(1 for _ in r.iter_lines()) > 10
            assert wait_final(c, sid)["state"] == "succeeded"
            assert (
                c.post("/api/v1/sessions/ffff00001111/actions", json={"action": "pause"}).status_code == 404
            )
        with httpx.Client(
            base_url=server.base, headers={"Authorization": "Bearer " + server.token[:-1]}
        ) as c:
            assert c.post("/api/v1/sessions", json=LONG).status_code == 401
    finally:
        code = server.interrupt()
    out, err = "".join(server.stdout), "".join(server.stderr)
    assert code in (0, 130)
    assert out.count(server.token) == 1
    assert server.token not in err
    assert "DEBUG" in err or "INFO" in err  # the logs were there to be scanned


def test_no_log_record_of_the_server_carries_the_token(
    served: Served, caplog: pytest.LogCaptureFixture
) -> None:
    from tests.api.conftest import TOKEN

    caplog.set_level(logging.DEBUG)
    with httpx.Client(base_url=served.base, timeout=30) as browser:
        browser.get("/", params={"token": TOKEN})
        browser.get("/", params={"token": TOKEN + "x"})
    with served.client() as c:
        sid = c.post("/api/v1/sessions", json={**LONG, "params": {"cycles": 3, "joints": [1]}}).json()["id"]
        wait_final(c, sid)
        assert c.get("/api/v1/events", headers={"Last-Event-ID": "bad"}).status_code == 422
    logging.getLogger("uvicorn.access").info(
        '%s - "%s %s HTTP/%s" %d', "127.0.0.1:1", "GET", f"/?token={TOKEN}", "1.1", 303
    )
    server_side = [
        r for r in caplog.records if not r.name.startswith(("httpx", "httpcore"))
    ]  # not our client
    assert any(r.name.startswith("uvicorn") for r in server_side)
    assert any(r.name.startswith(("api", "station")) for r in server_side)
    for record in server_side:
        assert TOKEN not in record.getMessage()
        assert TOKEN not in str(record.args)


@pytest.mark.slow
def test_ctrl_c_interrupts_the_session_and_a_restart_resumes_it(tmp_path: Path) -> None:
    data = tmp_path / "data"
    token = "restart-test-token-0123456789"
    env = {"STATION_API_TOKEN": token}
    first = ServeProcess(data, env=env)
    try:
        first.wait_url()
        first.token = token
        with first.client() as c:
            sid = c.post("/api/v1/sessions", json=LONG).json()["id"]  # far longer than this test
            wait_state(c, sid, {"running"})
            while c.get(f"/api/v1/sessions/{sid}").json()["progress"]["done"] < 3:
                pass
            assert c.get(f"/api/v1/sessions/{sid}").json()["state"] not in FINAL
    finally:
        code = first.interrupt()
    err = "".join(first.stderr)
    assert code in (0, 130), err[-3000:]
    assert "is interrupted (the robot is stopped)" in err, err[-3000:]
    assert "stop sent" in err, err[-3000:]  # the robot was stopped through its latched stop
    assert token not in err + "".join(first.stdout)

    second = ServeProcess(data, env=env)
    try:
        second.wait_url()
        second.token = token
        with second.client() as c:
            doc = c.get(f"/api/v1/sessions/{sid}").json()
            assert doc["state"] == "interrupted"
            done_before = len([s for s in second_steps(data, sid) if s.state == "done"])
            r = c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "resume"})
            assert r.status_code == 201, r.text
            assert r.json()["state"] not in FINAL
            while c.get(f"/api/v1/sessions/{sid}").json()["progress"]["done"] < 3:
                pass
            assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "stop"}).status_code == 201
            final = wait_final(c, sid)
            assert final["state"] == "stopped", final["error"]
        assert len([s for s in second_steps(data, sid) if s.state == "done"]) > done_before
    finally:
        second.interrupt()


def second_steps(data: Path, sid: str) -> list[Any]:
    from station.record import Record

    with Record(data) as record:
        return list(record.steps(sid))


@pytest.mark.slow
def test_a_killed_service_leaves_the_session_interrupted_and_resumable(tmp_path: Path) -> None:
    data = tmp_path / "data"
    token = "restart-test-token-0123456789"
    env = {"STATION_API_TOKEN": token}
    first = ServeProcess(data, env=env)
    first.wait_url()
    first.token = token
    with first.client() as c:
        sid = c.post("/api/v1/sessions", json={**LONG, "params": {"cycles": 40, "joints": [1]}}).json()["id"]
        wait_state(c, sid, {"running"})
        while c.get(f"/api/v1/sessions/{sid}").json()["progress"]["done"] < 3:
            pass
    first.proc.kill()  # no clean-up at all: the process dies mid-session
    first.finish()
    second = ServeProcess(data, env=env)
    try:
        second.wait_url()
        second.token = token
        with second.client() as c:
            assert c.get(f"/api/v1/sessions/{sid}").json()["state"] == "interrupted"
            assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "resume"}).status_code == 201
            assert wait_final(c, sid)["state"] == "succeeded"
    finally:
        second.interrupt()
