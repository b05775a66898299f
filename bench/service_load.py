"""The service under load: concurrent clients polling and streaming on loopback while a session runs.

``load(base, token, session_id, ...)`` runs ``clients`` asyncio clients against a running service: most
poll (session, station, prompt, session list), ``streamers`` of them follow the session's event stream
and reconnect with Last-Event-ID. It stops when the session has ended or ``max_s`` has passed (and after
``max_requests``), and returns request counts, errors and latency percentiles.

``python -m bench.service_load [--clients 50] [--seconds 60] [--rounds 3] [--time-scale 1]``: one
repeatability session on the simulated station, ``seconds`` of clients split into ``rounds`` windows
alternating with windows as long without clients; prints requests/s, p50/p99 latency, errors, and the
runner's cycle period and per-cycle software overhead over the quiet and over the loaded windows. The
clients run in a process of their own, as browsers do; the service runs its session in its worker
process (``station.worker``), as ``station serve`` does.

The overhead is ``bench.sessions_bench``'s (``make bench``'s station figure): a cycle's period on the
runner's thread (one step's start to the next's) less the arm's motion time for the cycle's moves (the
twin's trapezoid profiles, divided by the twin's time scale), the plan's deliberate settle wait and the
simulated camera's grab time (rendering a frame, which a real camera does not charge to the station).
What remains is the station's own software on the arm's critical path; the issue's goal is that it
stays within 10 % of its figure without clients. By default the twin runs at real time (``time_scale``
1, as ``make bench``); ``--time-scale 100`` (the service's default) shrinks the motion so that the
software dominates the period. Traffic goes to 127.0.0.1 only.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import json
import multiprocessing
import statistics
import sys
import tempfile
import threading
import time
from concurrent.futures import ProcessPoolExecutor
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
    started_at: float = 0.0
    """``time.perf_counter()`` when the clients started (the system's monotonic clock on Linux, the same
    in every process of the machine)."""

    def merge(self, other: LoadStats) -> None:
        """Add another run's counts (the windows of one benchmark)."""
        self.requests += other.requests
        self.errors += other.errors
        self.latencies_s += other.latencies_s
        self.events += other.events
        self.reconnects += other.reconnects
        self.seconds += other.seconds

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
        t0 = stats.started_at = time.perf_counter()
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


class CycleMeter:
    """Times a simulated station's repeatability cycles the way ``bench.sessions_bench`` does.

    Built in the station's worker process (:func:`install_meter`, through ``StationService.in_worker``):
    it wraps the sim camera's ``grab`` (timed) and listens to the runner's events there; :meth:`overhead`
    then splits each cycle of a session into motion, settle, camera and software. The listener runs on
    the runner's thread: it only notes a time and the twin's last move (no copying).
    """

    def __init__(self, devices: Any, speed_pct: float, settle_s: float) -> None:
        self.devices = devices
        self.speed_pct = speed_pct
        self.settle_s = settle_s
        self.arm = devices.truth.twin.arm
        self.time_scale = float(self.arm.params.time_scale)
        self.started: dict[tuple[str, int], tuple[float, Any]] = {}
        self.grabs: dict[tuple[str, int], float] = {}
        self._step: tuple[str, int] | None = None
        camera = devices.camera
        real_grab = camera.grab

        def timed_grab(timeout_s: float = 2.0) -> Any:
            t0 = time.perf_counter()
            try:
                return real_grab(timeout_s)
            finally:
                if self._step is not None:
                    self.grabs[self._step] = time.perf_counter() - t0

        camera.grab = timed_grab

    def on_event(self, e: Any) -> None:
        if e.type == "step_started":
            log = self.arm.motion_log
            key = (e.session_id, int(e.data["index"]))
            self._step = key
            self.started[key] = (time.perf_counter(), log[-1] if log else None)

    def overhead(self, session_id: str, windows: list[tuple[float, float]] | None = None) -> Any:
        """Per-cycle figures (ms) over the session's cycles (steps 1..; step 0 is the reference capture)
        that ran wholly within one of ``windows`` (perf_counter times), or all of them: call it right after
        the session ended (the twin keeps its last 1,000 moves)."""
        from bench.sessions_bench import _motion_time

        twin = self.devices.truth.twin
        log = list(self.arm.motion_log)
        where = {id(m): i for i, m in enumerate(log)}
        steps = sorted(i for sid, i in self.started if sid == session_id)
        rows = []
        for a, b in itertools.pairwise(steps):
            if a == 0 or b != a + 1:
                continue
            (t_a, m_a), (t_b, m_b) = self.started[(session_id, a)], self.started[(session_id, b)]
            if windows is not None and not any(lo <= t_a and t_b <= hi for lo, hi in windows):
                continue
            if m_a is None or m_b is None or id(m_a) not in where or id(m_b) not in where:
                continue
            moves = log[where[id(m_a)] + 1 : where[id(m_b)] + 1]
            motion = sum(_motion_time(twin, m.start_deg, m.end_deg, self.speed_pct) for m in moves)
            motion /= self.time_scale
            grab = self.grabs.get((session_id, a), 0.0)
            rows.append((t_b - t_a, motion, grab))
        if not rows:
            return {"cycles": 0}
        period = [r[0] for r in rows]
        software = [p - m - g - self.settle_s for p, m, g in rows]
        return {
            "cycles": len(rows),
            "period_ms": round(statistics.mean(period) * 1000, 2),
            "period_median_ms": round(statistics.median(period) * 1000, 2),
            "motion_ms": round(statistics.mean(r[1] for r in rows) * 1000, 2),
            "settle_ms": round(self.settle_s * 1000, 2),
            "camera_ms": round(statistics.mean(r[2] for r in rows) * 1000, 2),
            "software_ms": round(statistics.mean(software) * 1000, 2),
            "software_median_ms": round(statistics.median(software) * 1000, 2),
        }


_METER: CycleMeter | None = None


def install_meter(host: Any, speed_pct: float, settle_s: float) -> None:
    """In the station's worker: time its cycles from now on."""
    global _METER
    _METER = CycleMeter(host.devices, speed_pct, settle_s)
    host.subscribe(_METER.on_event)


def meter_overhead(host: Any, session_id: str, windows: list[tuple[float, float]] | None) -> Any:
    """In the station's worker: :meth:`CycleMeter.overhead` of the installed meter."""
    if _METER is None:
        raise RuntimeError("no cycle meter installed in this worker")
    return _METER.overhead(session_id, windows)


def main() -> None:
    import uvicorn

    from api import Access, ServeLimits, ServiceSettings, StationService, create_app, server_config

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clients", type=int, default=50)
    parser.add_argument("--streamers", type=int, default=10)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--rounds", type=int, default=3, help="quiet and loaded windows, alternating")
    parser.add_argument("--cycles", type=int, default=0, help="the session's cycles (default: enough)")
    parser.add_argument("--time-scale", type=float, default=1.0, help="the twin's time scale (1: real time)")
    parser.add_argument(
        "--switch-interval", type=float, default=None, help="sys.setswitchinterval (s) for this run"
    )
    parser.add_argument(
        "--worker-nice", type=int, default=None, help="the station worker's nice value (default: -10)"
    )
    parser.add_argument("--loop", default="auto", help="uvicorn's event loop (auto: uvloop when installed)")
    parser.add_argument("--http", default="auto", help="uvicorn HTTP parser (auto: httptools if installed)")
    args = parser.parse_args()
    if args.switch_interval is not None:
        sys.setswitchinterval(args.switch_interval)
    token = "bench-token-0123456789abcdef"
    speed_pct, settle_s = 80, 0.25
    with tempfile.TemporaryDirectory() as tmp:
        service = StationService(
            ServiceSettings(
                sim=True,
                data=Path(tmp),
                sim_options={"seed": 0, "time_scale": args.time_scale},
                **({} if args.worker_nice is None else {"worker_nice": args.worker_nice}),
            )
        )
        # the meter's hooks by their importable name (this file may run as __main__)
        from bench import service_load as hooks

        service.in_worker(hooks.install_meter, speed_pct, settle_s)
        service_nice = service.worker.info.nice
        app = create_app(service, Access(token))  # the clients send the token, as every client must
        options: dict[str, Any] = {"host": "127.0.0.1", "port": 0, "loop": args.loop}
        if args.http == "auto":  # station serve's own: httptools with its header timeout and limits
            config = server_config(app, ServeLimits(), **options)
        else:
            config = uvicorn.Config(
                app, access_log=False, log_config=None, lifespan="on", http=args.http, **options
            )
        server = uvicorn.Server(config)
        thread = threading.Thread(target=server.run, daemon=True)
        thread.start()
        while not server.started:
            time.sleep(0.01)
        base = f"http://127.0.0.1:{server.servers[0].sockets[0].getsockname()[1]}"
        # one session for the whole run, quiet and loaded windows alternating (``--rounds``): the machine's
        # other work drifts over minutes, and each figure then sees the same mix of it
        window_s = args.seconds / args.rounds
        cycles = args.cycles or int(2 * args.seconds / (0.6 if args.time_scale <= 1 else 0.3)) + 20
        params = {
            "cycles": cycles,
            "joints": [1],
            "warmup_cycles": 0,
            "speed_pct": speed_pct,
            "settle_s": settle_s,
        }
        quiet_windows: list[tuple[float, float]] = []
        loaded_windows: list[tuple[float, float]] = []
        total = LoadStats()
        try:
            sid = service.create_session("repeatability", params).row.id
            # the clients run in a process of their own, as the operator's browsers and scripts do (the
            # runner runs in the service's worker process, the service's HTTP side in this one)
            with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
                pool.submit(time.sleep, 0).result()  # the process is up before the first window
                for _ in range(args.rounds):
                    t0 = time.perf_counter()
                    time.sleep(window_s)
                    quiet_windows.append((t0, time.perf_counter()))
                    stats = pool.submit(
                        load,
                        base,
                        token,
                        sid,
                        clients=args.clients,
                        streamers=args.streamers,
                        max_s=window_s,
                    ).result()
                    loaded_windows.append((stats.started_at, time.perf_counter()))
                    total.merge(stats)
            ended = service.reads.session_ended(sid)
            with contextlib.suppress(Exception):
                service.act(sid, "abort")
            service.wait()
            quiet_over = service.in_worker(hooks.meter_overhead, sid, quiet_windows)
            loaded_over = service.in_worker(hooks.meter_overhead, sid, loaded_windows)
        finally:
            server.should_exit = True
            thread.join(30)
            service.close()
    if ended:
        raise SystemExit("the session ended before the run did: give more --cycles")
    out = {
        **total.summary(),
        "clients": args.clients,
        "streamers": args.streamers,
        "rounds": args.rounds,
        "time_scale": args.time_scale,
        "switch_interval_s": sys.getswitchinterval(),
        "worker_nice": service_nice,
        "uvicorn": {"loop": args.loop, "http": args.http},
        "overhead_quiet": quiet_over,
        "overhead_loaded": loaded_over,
        "cycle_period_growth_pct": _growth(quiet_over, loaded_over, "period_ms"),
        "overhead_growth_pct": _growth(quiet_over, loaded_over, "software_ms"),
    }
    print(json.dumps(out, indent=2))
    results = Path(__file__).parent / "results"
    results.mkdir(exist_ok=True)
    (results / "service_load.json").write_text(json.dumps(out, indent=2) + "\n")


def _growth(quiet: dict[str, Any], loaded: dict[str, Any], key: str) -> float | None:
    if not quiet.get("cycles") or not loaded.get("cycles"):
        return None
    return round((loaded[key] / quiet[key] - 1) * 100, 1)


if __name__ == "__main__":
    main()
