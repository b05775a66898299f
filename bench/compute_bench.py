"""``make bench``, the compute backends (issue 24): what one frame costs, and frames per second where.

* **Per-frame cost on one core** (this thread's CPU time, so that other jobs on the machine do not
  inflate it): PNG decode, measurement, and the bookkeeping around them (the result object, its JSON
  line; and, for a pool or a cluster, pickling the result back), each the median over the frames of a
  round. The issue's target: decode + measure + bookkeeping <= 4 ms.
* **Start-up of ``station measure``** on one file: CPU seconds of the whole process (what a short run
  pays before its first frame), and wall seconds.
* **Throughput** (frames/s, wall clock, start-up excluded: each backend measures a few frames first)
  for the local backend with 1 job and with all cores, and a ``distributed.LocalCluster`` of 1 and of 2
  workers; rounds interleave the backends, so that a burst of load from other jobs hits them alike.
  Beside them the machine's parallel capacity at the time (``bench.timing.parallel_capacity``: 1.0
  when each of the cores is ours alone). Cluster efficiency: a cluster's frames/s over the local pool's
  at equal cores, paired round by round (the issue's target: >= 0.8).
* **CPU per frame** of each backend: the CPU time of this process and every process it started (the
  pool's, the cluster's workers; the LocalClusters' schedulers run in this process) over a run, per
  frame. Where other jobs share the cores, wall-clock rates say more about them than about us; CPU
  per frame does not, and its ratio to one job's is the backend's efficiency at any load.

Written to ``bench/results/compute.json``. ``python -m bench.compute_bench [--files N] [--rounds R]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import pickle
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import psutil

from bench.timing import cores, parallel_capacity
from sim.imageset import render_random_set
from station.batch import FileResult
from station.compute import ComputeSpec, MeasureBackend, open_backend
from station.imageio import load_image
from station.imagesets import load_set
from station.runtime import tune_allocator
from station.vision import MeasureParams, measure

RESULTS = Path(__file__).parent / "results" / "compute.json"
PARAMS = MeasureParams()
WARM_FRAMES = 8
PER_FRAME_TARGET_MS = 4.0
EFFICIENCY_TARGET = 0.8


def _median_ms(times: Sequence[float]) -> float:
    return 1000.0 * statistics.median(times)


def per_frame_cost(files: Sequence[Path], rounds: int) -> dict[str, list[float]]:
    """Per round, the median thread-CPU ms per frame of each stage (see the module's docstring)."""
    out: dict[str, list[float]] = {k: [] for k in ("decode", "measure", "bookkeeping", "pickle", "total")}
    for path in files[:3]:  # warm caches (kernels, allocator, OpenCV's first calls)
        json.dumps(FileResult.for_path(path, measurement=measure(load_image(path).image, PARAMS)).to_json())
    for _ in range(rounds):
        stage: dict[str, list[float]] = {k: [] for k in out}
        for path in files:
            t0 = time.thread_time()
            loaded = load_image(path)
            t1 = time.thread_time()
            m = measure(loaded.image, PARAMS)
            t2 = time.thread_time()
            result = FileResult.for_path(path, measurement=m)
            json.dumps(result.to_json())
            t3 = time.thread_time()
            pickle.loads(pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL))
            t4 = time.thread_time()
            for key, dt in (("decode", t1 - t0), ("measure", t2 - t1), ("bookkeeping", t3 - t2)):
                stage[key].append(dt)
            stage["pickle"].append(t4 - t3)
            stage["total"].append(t3 - t0)
        for key, times in stage.items():
            out[key].append(_median_ms(times))
    return out


def startup(one: Path, repeats: int) -> dict[str, list[float]]:
    """``station measure --json ONE``: CPU seconds (user + system, the whole process) and wall seconds."""
    station = Path(sys.executable).with_name("station")
    cpu, wall = [], []
    for _ in range(repeats):
        before = os.times()
        t0 = time.perf_counter()
        subprocess.run([str(station), "measure", "--json", str(one)], capture_output=True, check=True)
        wall.append(time.perf_counter() - t0)
        after = os.times()
        cpu.append(
            (after.children_user - before.children_user) + (after.children_system - before.children_system)
        )
    return {"cpu_s": cpu, "wall_s": wall}


def _tree_cpu_s() -> float:
    """CPU seconds (user + system) of this process and of every process below it, now."""
    me = psutil.Process()
    total = 0.0
    for proc in [me, *me.children(recursive=True)]:
        with contextlib.suppress(psutil.Error):
            t = proc.cpu_times()
            total += t.user + t.system
    return total


def _run(backend: MeasureBackend, files: Sequence[Path]) -> tuple[float, float]:
    """(frames/s wall clock, CPU ms per frame) of one run."""
    cpu0, t0 = _tree_cpu_s(), time.perf_counter()
    n = sum(1 for r in backend.measure(files, PARAMS) if r.ok)
    elapsed, cpu = time.perf_counter() - t0, _tree_cpu_s() - cpu0
    if n != len(files):
        raise RuntimeError(f"{backend.name}: only {n} of {len(files)} frames were measured")
    return len(files) / elapsed, 1000.0 * cpu / len(files)


def throughput(files: Sequence[Path], rounds: int) -> dict[str, Any]:
    """frames/s per backend per round (interleaved), with the machine's parallel capacity per round."""
    n = cores()
    specs: dict[str, Callable[[], ComputeSpec]] = {
        "local, 1 job": lambda: ComputeSpec(jobs=1),
        f"local, {n} jobs": lambda: ComputeSpec(jobs=n),
        "LocalCluster, 1 worker": lambda: ComputeSpec.of("local:1"),
        f"LocalCluster, {n} workers": lambda: ComputeSpec.of(f"local:{n}"),
    }
    fps: dict[str, list[float]] = {name: [] for name in specs}
    cpu_ms: dict[str, list[float]] = {name: [] for name in specs}
    capacity: list[float] = []
    for r in range(rounds):
        names = list(specs)
        names = names[r % len(names) :] + names[: r % len(names)]  # no backend always runs first
        for name in names:
            # one backend alive at a time: an idle cluster's event loops and monitors are not charged
            # to another's run
            print(f"  round {r + 1}: {name} ...", file=sys.stderr, flush=True)
            with contextlib.closing(open_backend(specs[name]())) as backend:
                list(backend.measure(files[:WARM_FRAMES], PARAMS))  # start-up (a cluster's) excluded
                rate, cost = _run(backend, files)
            fps[name].append(rate)
            cpu_ms[name].append(cost)
        capacity.extend(parallel_capacity(n, repeats=1))
    pool, cluster = fps[f"local, {n} jobs"], fps[f"LocalCluster, {n} workers"]
    single, cluster1 = fps["local, 1 job"], fps["LocalCluster, 1 worker"]
    return {
        "cores": n,
        "frames": len(files),
        "frames_per_s": fps,
        "cpu_ms_per_frame": cpu_ms,
        "cpu_efficiency": {
            name: [a / b for a, b in zip(cpu_ms["local, 1 job"], v, strict=True)]
            for name, v in cpu_ms.items()
        },
        "machine_parallel_capacity": capacity,
        "cluster_efficiency_equal_cores": [c / p for c, p in zip(cluster, pool, strict=True)],
        "cluster_efficiency_1_worker": [c / s for c, s in zip(cluster1, single, strict=True)],
        "pool_speedup": [p / s for p, s in zip(pool, single, strict=True)],
    }


def _span(values: Sequence[float], fmt: str = ".2f") -> str:
    return f"{min(values):{fmt}}-{max(values):{fmt}}" if len(values) > 1 else f"{values[0]:{fmt}}"


def render(results: dict[str, Any]) -> str:
    cost, start, tp = results["per_frame_ms"], results["startup"], results["throughput"]
    total = cost["total"]
    lines = [
        f"per frame on one core (thread CPU ms, median per round; {results['frame_size']} PNGs):",
        *(f"  {k:<12} {_span(v)}" for k, v in cost.items() if k != "total"),
        f"  {'total':<12} {_span(total)} (decode + measure + bookkeeping; target <= {PER_FRAME_TARGET_MS:g}: "
        f"met in {sum(t <= PER_FRAME_TARGET_MS for t in total)} of {len(total)} rounds); 'pickle' is what a "
        "pool or a cluster adds to send the result back",
        f"station measure start-up, one file: {_span(start['cpu_s'])} s CPU, {_span(start['wall_s'])} s wall",
        f"throughput, {tp['frames']} frames, start-up excluded (range over rounds): frames/s wall clock; "
        "CPU ms per frame (all our processes); CPU efficiency (1 job's CPU per frame over this one's)",
        *(
            f"  {name:<24} {_span(v, '.0f'):>9} fps  {_span(tp['cpu_ms_per_frame'][name])} ms CPU  "
            f"{_span(tp['cpu_efficiency'][name])}"
            for name, v in tp["frames_per_s"].items()
        ),
        f"  machine's parallel capacity for {tp['cores']} processes: "
        f"{_span(tp['machine_parallel_capacity'])} (1.0: every core ours alone; this machine is shared)",
        f"  local pool speed-up over 1 job: {_span(tp['pool_speedup'])}",
        f"  cluster efficiency at equal cores (LocalCluster {tp['cores']} / local {tp['cores']} jobs): "
        f"{_span(tp['cluster_efficiency_equal_cores'])} (target >= {EFFICIENCY_TARGET}); 1 worker / 1 job: "
        f"{_span(tp['cluster_efficiency_1_worker'])}",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench.compute_bench", description=__doc__.splitlines()[0]
    )
    parser.add_argument("--files", type=int, default=480, help="640x480 PNGs measured per backend per round")
    parser.add_argument("--rounds", type=int, default=3, help="rounds (ranges are over these)")
    parser.add_argument("--data", type=Path, default=Path("bench/results/data"), help="rendered sets")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    tune_allocator()  # as the station's command line does
    root = args.data / f"random-nominal-{args.files}"
    if not (root / "truth.json").exists():
        print(f"compute bench: rendering {args.files} frames ...", file=sys.stderr)
        render_random_set(root, preset="nominal", count=args.files, seed=11, force=True)
    files = list(load_set(root).files)
    print("compute bench: per-frame cost ...", file=sys.stderr, flush=True)
    results: dict[str, Any] = {"frame_size": "640x480 nominal", "load_average": os.getloadavg()}
    results["per_frame_ms"] = per_frame_cost(files, args.rounds)
    print("compute bench: station measure start-up ...", file=sys.stderr, flush=True)
    results["startup"] = startup(files[0], args.rounds)
    print("compute bench: throughput ...", file=sys.stderr, flush=True)
    results["throughput"] = throughput(files, args.rounds)
    results["load_average_after"] = os.getloadavg()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2))
    print(render(results))
    print(f"load average before / after: {results['load_average']} / {results['load_average_after']}")
    print(f"(written to {args.out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
