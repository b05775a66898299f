"""The service under load: concurrent clients polling and streaming on loopback while a session runs.

``load(base, token, session_id, ...)`` runs ``clients`` asyncio clients against a running service: most
poll (session, station, prompt, session list), ``streamers`` of them follow the session's event stream
and reconnect with Last-Event-ID. It stops when the session has ended or ``max_s`` has passed (and after
``max_requests``), and returns request counts, errors and latency percentiles.

``python -m bench.service_load [--clients 50] [--seconds 60]``: a repeatability session on the simulated
station without clients and then with them; prints requests/s, p50/p99 latency, errors, and the runner's
cycle period both ways (the stall the clients cause). Traffic goes to 127.0.0.1 only.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import json
import statistics
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx

FINAL = {"stopped", "aborted", "failed", "succeeded", "interrupted"}
POLL_S = 0.5
"""Each polling client's pause between requests (the operator page polls every 2 s)."""


@dataclass
class LoadStats:
    requests: int = 0
    errors: list[str] = field(default_factory=list)
    latencies_s: list[float] = field(default_factory=list)
    events: int = 0
    reconnects: int = 0
    seconds: float = 0.0

    def summary(self) -> dict[str, Any]:
        lat = sorted(self.latencies_s)

        def pct(p: float) -> float | None:
            return round(lat[min(len(lat) - 1, int(p * len(lat)))] * 1000, 2) if lat else None

        return {
            "requests": self.requests,
            "errors": len(self.errors),
            "first_errors": self.errors[:5],
            "requests_per_s": round(self.requests / self.seconds, 1) if self.seconds else None,
            "p50_ms": pct(0.50),
            "p99_ms": pct(0.99),
            "stream_events": self.events,
            "stream_reconnects": self.reconnects,
            "seconds": round(self.seconds, 2),
        }


async def _poller(c: httpx.AsyncClient, sid: str, stats: LoadStats, stop: asyncio.Event, k: int) -> None:
    paths = [f"/api/v1/sessions/{sid}", "/api/v1/station", "/api/v1/prompt", "/api/v1/sessions?limit=5"]
    i = k
    while not stop.is_set():
        path = paths[i % len(paths)]
        i += 1
        t0 = time.perf_counter()
        try:
            r = await c.get(path)
        except httpx.HTTPError as exc:
            stats.errors.append(f"GET {path}: {type(exc).__name__}: {exc}")
            continue
        stats.latencies_s.append(time.perf_counter() - t0)
        stats.requests += 1
        if r.status_code not in (200, 204):
            stats.errors.append(f"GET {path}: {r.status_code} {r.text[:200]}")
        elif path.endswith(sid) and r.json()["state"] in FINAL:
            stop.set()
        await asyncio.sleep(POLL_S)


async def _streamer(c: httpx.AsyncClient, sid: str, stats: LoadStats, stop: asyncio.Event) -> None:
    last = "0"
    while not stop.is_set():
        try:
            async with c.stream(
                "GET", f"/api/v1/sessions/{sid}/events", headers={"Last-Event-ID": last}
            ) as r:
                if r.status_code != 200:
                    stats.errors.append(f"stream: {r.status_code}")
                    return
                read = 0
                async for line in r.aiter_lines():
                    if line.startswith("id: "):
                        last = line[4:]
                        stats.events += 1
                        read += 1
                    if stop.is_set() or read >= 200:  # hang up now and then: the client vanishes mid-stream
                        break
        except httpx.HTTPError as exc:
            stats.errors.append(f"stream: {type(exc).__name__}: {exc}")
            return
        stats.reconnects += 1
        if not stop.is_set():
            await asyncio.sleep(0.05)


async def _load(
    base: str, token: str, sid: str, clients: int, streamers: int, max_s: float, max_requests: int
) -> LoadStats:
    stats = LoadStats()
    stop = asyncio.Event()
    # idle connections are dropped by the client (2 s) before uvicorn's keep-alive timeout (5 s) closes
    # them, or a request sent on one as the server closes it fails (the keep-alive race)
    limits = httpx.Limits(
        max_connections=clients + 5, max_keepalive_connections=clients + 5, keepalive_expiry=2.0
    )
    headers = {"Authorization": f"Bearer {token}"}
    async with httpx.AsyncClient(base_url=base, headers=headers, timeout=30, limits=limits) as c:
        t0 = time.perf_counter()
        tasks = [asyncio.create_task(_streamer(c, sid, stats, stop)) for _ in range(streamers)]
        tasks += [asyncio.create_task(_poller(c, sid, stats, stop, k)) for k in range(clients - streamers)]

        async def bound() -> None:
            while not stop.is_set():
                if time.perf_counter() - t0 > max_s or stats.requests >= max_requests:
                    stop.set()
                await asyncio.sleep(0.05)

        tasks.append(asyncio.create_task(bound()))
        await asyncio.gather(*tasks)
        stats.seconds = time.perf_counter() - t0
    return stats


def load(
    base: str,
    token: str,
    session_id: str,
    *,
    clients: int = 50,
    streamers: int = 10,
    max_s: float = 60.0,
    max_requests: int = 1_000_000,
) -> LoadStats:
    """Run the clients until the session ends (or the bounds); loopback addresses only."""
    host = httpx.URL(base).host
    if host not in ("127.0.0.1", "localhost", "::1"):
        raise ValueError(f"load tests target this machine only (127.0.0.1), not {host}")
    return asyncio.run(_load(base, token, session_id, clients, streamers, max_s, max_requests))


def cycle_period_s(record: Any, session_id: str) -> float:
    """The runner's median step period (s) from the session's step_finished events."""
    times = [
        e.time.timestamp() for e in record.events(session_id, limit=100_000) if e.type == "step_finished"
    ]
    gaps = [b - a for a, b in itertools.pairwise(times)]
    return statistics.median(gaps) if gaps else float("nan")


def main() -> None:
    import uvicorn

    from api import Access, ServiceSettings, StationService, create_app

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clients", type=int, default=50)
    parser.add_argument("--streamers", type=int, default=10)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--cycles", type=int, default=300)
    args = parser.parse_args()
    token = "bench-token-0123456789abcdef"
    with tempfile.TemporaryDirectory() as tmp:
        service = StationService(ServiceSettings(sim=True, data=Path(tmp)))
        app = create_app(service, Access(token, True))
        server = uvicorn.Server(
            uvicorn.Config(app, host="127.0.0.1", port=0, access_log=False, log_config=None, lifespan="on")
        )
        thread = threading.Thread(target=server.run, daemon=True)
        thread.start()
        while not server.started:
            time.sleep(0.01)
        base = f"http://127.0.0.1:{server.servers[0].sockets[0].getsockname()[1]}"
        params = {"cycles": args.cycles, "joints": [1], "warmup_cycles": 0}
        try:
            quiet = service.create_session("repeatability", params).row.id
            service.wait()
            with_clients = service.create_session("repeatability", params).row.id
            stats = load(
                base, token, with_clients, clients=args.clients, streamers=args.streamers, max_s=args.seconds
            )
            with contextlib.suppress(Exception):
                service.act(with_clients, "abort")
            service.wait()
            quiet_s = cycle_period_s(service.record, quiet)
            loaded_s = cycle_period_s(service.record, with_clients)
        finally:
            server.should_exit = True
            thread.join(30)
    out = {
        **stats.summary(),
        "clients": args.clients,
        "streamers": args.streamers,
        "cycle_period_quiet_ms": round(quiet_s * 1000, 2),
        "cycle_period_loaded_ms": round(loaded_s * 1000, 2),
        "runner_stall_pct": round((loaded_s / quiet_s - 1) * 100, 1),
    }
    print(json.dumps(out, indent=2))
    results = Path(__file__).parent / "results"
    results.mkdir(exist_ok=True)
    (results / "service_load.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
