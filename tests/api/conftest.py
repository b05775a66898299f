"""Fixtures of the service's tests: a real uvicorn server on 127.0.0.1 (port chosen by the kernel) over a
StationService on the simulated station, and httpx clients for it.

A real server, not Starlette's TestClient (which warns about httpx, and the suite's warnings are
errors); it is also what the browser and the load tests talk to.
"""

from __future__ import annotations

import threading
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
import uvicorn

from api import Access, AllowedHosts, ServeLimits, ServiceSettings, StationService, create_app, server_config

TOKEN = "test-token-0123456789abcdef-ABCDEF"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
FINAL = {"stopped", "aborted", "failed", "succeeded", "interrupted"}


@dataclass
class Served:
    service: StationService
    server: uvicorn.Server
    thread: threading.Thread
    base: str

    def client(
        self, *, token: bool = True, headers: dict[str, str] | None = None, **kwargs: Any
    ) -> httpx.Client:
        merged = {**(AUTH if token else {}), **(headers or {})}
        return httpx.Client(base_url=self.base, headers=merged, timeout=30.0, **kwargs)

    @property
    def app(self) -> Any:
        """The FastAPI app (its ``state``: the access, the limits, ``/measure``'s gate)."""
        return self.server.config.app

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(30)


def serve(
    service: StationService,
    access: Access,
    *,
    limits: ServeLimits | None = None,
    hosts: AllowedHosts | None = None,
) -> Served:
    """``station serve``'s app and server (its limits and Host check) on 127.0.0.1, any free port."""
    lim = limits or ServeLimits()
    app = create_app(service, access, limits=lim, hosts=hosts)
    config = server_config(app, lim, host="127.0.0.1", port=0, timeout_graceful_shutdown=2)
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, name="uvicorn-test", daemon=True)
    thread.start()
    while not server.started:
        if not thread.is_alive():
            raise RuntimeError("the test server did not start")
        time.sleep(0.01)
    port = server.servers[0].sockets[0].getsockname()[1]
    return Served(service, server, thread, f"http://127.0.0.1:{port}")


ServeFactory = Callable[..., Served]


@pytest.fixture
def data_dir(tmp_path: Path) -> Path:
    return tmp_path / "data"


#: Test modules whose tests share one service per set of ``make_served`` options (a module's service,
#: in a data directory of the module's), and which of their services: those tests only read, measure or
#: are refused, so that none changes what another sees, in any order. Every other service is one test's
#: own (a test that starts sessions, imports, injects faults or counts files needs its own).
SHARED_SERVICES: dict[str, Callable[[dict[str, Any]], bool]] = {
    "tests.api.test_measure": lambda options: not options,  # the default service: it only measures
    "tests.api.test_fuzz": lambda options: not options,  # reads the schema; the fuzzer is refused or reads
    "tests.api.test_auth": lambda options: options == {"sim": False},  # the offline one: reads, refusals
    # offline services with tight limits: uploads measured or refused, stalled or dropped connections
    # (no session is created: a refused body never reaches the route)
    "tests.api.test_limits": lambda options: options.get("sim") is False,
}


@pytest.fixture(scope="module")
def module_services(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Served]]:
    """The services a module's tests share (see ``SHARED_SERVICES``), stopped after its last test."""
    shared: dict[str, Served] = {}
    yield shared
    for s in shared.values():
        s.stop()


@pytest.fixture
def make_served(
    request: pytest.FixtureRequest,
    data_dir: Path,
    module_services: dict[str, Served],
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[ServeFactory]:
    """``make_served(sim=True, manual=False, public_read=False, limits=None, database=None,
    **sim_options)`` -> a running server (the module's shared one where ``SHARED_SERVICES`` says so)."""
    started: list[Served] = []
    shares = SHARED_SERVICES.get(request.module.__name__)

    def build(options: dict[str, Any], data: Path) -> Served:
        sim_options = dict(options)
        sim = sim_options.pop("sim", True)
        manual = sim_options.pop("manual", False)
        public_read = sim_options.pop("public_read", False)
        limits = sim_options.pop("limits", None)
        database = sim_options.pop("database", None)
        settings = ServiceSettings(
            sim=sim, manual_prompts=manual, data=data, database=database, sim_options=sim_options
        )
        return serve(StationService(settings), Access(TOKEN, public_read), limits=limits)

    def make(**options: Any) -> Served:
        if shares is not None and shares(options):
            key = repr(sorted(options.items()))
            if key not in module_services:
                module_services[key] = build(options, tmp_path_factory.mktemp("shared") / "data")
            return module_services[key]
        served = build(options, data_dir)
        started.append(served)
        return served

    yield make
    for s in started:
        s.stop()


@pytest.fixture
def served(make_served: ServeFactory) -> Served:
    return make_served()


def wait_final(client: httpx.Client, session_id: str) -> dict[str, Any]:
    """Poll the session until it has ended (a hang fails through pytest-timeout)."""
    while True:
        doc: dict[str, Any] = client.get(f"/api/v1/sessions/{session_id}").json()
        if doc["state"] in FINAL:
            return doc
        time.sleep(0.05)


def wait_state(client: httpx.Client, session_id: str, states: set[str]) -> dict[str, Any]:
    while True:
        doc: dict[str, Any] = client.get(f"/api/v1/sessions/{session_id}").json()
        if doc["state"] in states:
            return doc
        if doc["state"] in FINAL:
            raise AssertionError(f"session ended {doc['state']} ({doc['error']}) before reaching {states}")
        time.sleep(0.02)


def acknowledge_stop(client: httpx.Client) -> dict[str, Any]:
    """Release the robot's latched stop as the page on the station does (this test's client is loopback);
    the reply says a stop was latched."""
    r = client.post("/api/v1/station/robot/acknowledge")
    assert r.status_code == 200, r.text
    doc: dict[str, Any] = r.json()
    assert doc["acknowledged"] is True, doc
    return doc


REMOTE_PEER = ("192.0.2.7", 50123)
"""A connection's peer on another machine (TEST-NET-1)."""


def remote_client(served: Served) -> Any:
    """A client whose connection comes from another machine (peer ``REMOTE_PEER``), with the token:
    Starlette's test client, on the served app, sets the peer as a TCP connection from there would."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # starlette.testclient's notice about its httpx dependency
        from starlette.testclient import TestClient
    return TestClient(served.app, base_url=served.base, client=REMOTE_PEER, headers=AUTH)
