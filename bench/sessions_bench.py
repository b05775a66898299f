"""Session benchmark: the runner's software overhead per capture-move-return cycle against the robot's
motion time (controller twin at real time, ``time_scale=1``), and the runner's resident memory over a
long session (capture 1,000 and capture 10,000).

Overhead per cycle = the cycle's period on the runner's thread (from one step's start to the next's)
- the twin's motion time for its moves (the trapezoid profiles it executes at the session's speed) - the
plan's deliberate settle wait before the capture (``settle_s``, default 0.25 s) - the camera's grab
time (the simulated camera renders a frame, which a real camera does not charge to the station). What
remains is the station's own work on the arm's critical path: the driver's polling for arrival and
the position read before a capture. Storing the PNG (fsync), measuring it and the record's rows run
in the store thread behind the arm and show here only if they fall behind it.

``python -m bench.sessions_bench [--cycles N] [--captures N]`` prints the numbers as JSON.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.record_bench import rss_mb
from sim._controller_arm import trapezoid_time
from sim.station import build_sim_station
from station.kinds import get_plan
from station.plans import parse_params
from station.record import EventRow, Record
from station.runner import SessionRunner, SessionState
from station.testing import FakeCamera, FakeStation, draw_cross


def _motion_time(twin: Any, start: tuple[float, ...], end: tuple[float, ...], speed_pct: float) -> float:
    s = twin.settings
    speeds = np.asarray(s.max_speed_deg_s) * speed_pct / 100.0
    return max(
        trapezoid_time(abs(b - a), v, acc)
        for a, b, v, acc in zip(start, end, speeds, s.accel_deg_s2, strict=True)
    )


def overhead(cycles: int = 8, joint: int = 1, speed_pct: int = 80, settle_s: float = 0.25) -> dict[str, Any]:
    """Run a one-joint repeatability session on the simulated station at real time."""
    devices = build_sim_station(seed=0, time_scale=1.0)
    sim = devices.truth
    grab_s: list[float] = []
    camera = devices.camera
    real_grab = camera.grab

    def timed_grab(timeout_s: float = 2.0) -> Any:
        t0 = time.perf_counter()
        try:
            return real_grab(timeout_s)
        finally:
            grab_s.append(time.perf_counter() - t0)

    camera.grab = timed_grab  # type: ignore[method-assign]
    started: dict[int, float] = {}
    motions_at: dict[int, int] = {}

    def on_event(e: EventRow) -> None:
        if e.type == "step_started":
            started[e.data["index"]] = time.perf_counter()
            motions_at[e.data["index"]] = len(sim.twin.motion_log)

    with tempfile.TemporaryDirectory() as tmp, Record(Path(tmp)) as record:
        plan = get_plan("repeatability")
        params = parse_params(
            plan,
            {
                "cycles": cycles,
                "warmup_cycles": 0,
                "joints": [joint],
                "speed_pct": speed_pct,
                "settle_s": settle_s,
            },
        )
        runner = SessionRunner(record, plan, params, devices=devices)
        runner.subscribe(on_event)
        try:
            state = runner.run()
        finally:
            devices.close_owned()
        if state is not SessionState.SUCCEEDED:
            raise RuntimeError(f"benchmark session {state}: {runner.error}")
        log = sim.twin.motion_log
    # cycle steps are 1..cycles (step 0 is the reference capture)
    rows = []
    grabs = iter(grab_s[1:])
    for index in range(1, cycles + 1):
        end = motions_at.get(index + 1, len(log))
        moves = log[motions_at[index] : end]
        motion = sum(_motion_time(sim.twin, m.start_deg, m.end_deg, speed_pct) for m in moves)
        grab = next(grabs)
        period = started[index + 1] - started[index] if index < cycles else float("nan")
        rows.append((period, motion, grab))
    table = np.array(rows[:-1], dtype=np.float64)  # the last cycle has no successor to time it by
    wall, motion_s, grab_s_arr = table[:, 0], table[:, 1], table[:, 2]
    software = wall - motion_s - grab_s_arr - settle_s  # the settle is the plan's deliberate wait
    return {
        "cycles": cycles,
        "wall_s_per_cycle": float(wall.mean()),
        "motion_s_per_cycle": float(motion_s.mean()),
        "camera_s_per_cycle": float(grab_s_arr.mean()),
        "settle_s_per_cycle": settle_s,
        "software_s_per_cycle": float(software.mean()),
        "software_over_motion": float(software.mean() / motion_s.mean()),
    }


def memory(captures: int = 10_000) -> dict[str, Any]:
    """Resident memory of a long fake session (in-process devices, real record and measurement)."""
    rng = np.random.default_rng(0)
    frames = [draw_cross(center_px=(320 + 0.1 * i, 240 - 0.07 * i), rng=rng) for i in range(16)]

    class CyclingCamera(FakeCamera):
        def grab(self, timeout_s: float = 2.0) -> Any:
            frame = super().grab(timeout_s)
            return frame.__class__(frames[frame.frame_id % len(frames)], frame.timestamp_s, frame.frame_id)

    fake = FakeStation(camera=CyclingCamera(frames=frames))
    marks: dict[int, float] = {}
    count = {"n": 0}

    def on_event(e: EventRow) -> None:
        if e.type == "image_captured":
            count["n"] += 1
            if count["n"] in (1_000, captures):
                marks[count["n"]] = rss_mb()

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, Record(Path(tmp)) as record:
        plan = get_plan("repeatability")
        params = parse_params(plan, {"cycles": captures - 1, "warmup_cycles": 0, "joints": [1]})
        runner = SessionRunner(record, plan, params, devices=fake.devices())
        runner.subscribe(on_event)
        state = runner.run()
        if state is not SessionState.SUCCEEDED:
            raise RuntimeError(f"benchmark session {state}: {runner.error}")
    elapsed = time.perf_counter() - t0
    return {
        "captures": captures,
        "rss_mb_at_1000": marks.get(1_000),
        f"rss_mb_at_{captures}": marks.get(captures),
        "rss_growth_mb": (marks[captures] - marks[1_000]) if captures in marks and 1_000 in marks else None,
        "captures_per_s": captures / elapsed,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=8)
    parser.add_argument("--captures", type=int, default=10_000)
    args = parser.parse_args()
    print(json.dumps({"overhead": overhead(args.cycles), "memory": memory(args.captures)}, indent=2))


if __name__ == "__main__":
    main()
