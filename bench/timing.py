"""Speed measurements for ``make bench`` (issue 12): ratios to the plain-OpenCV baseline, throughput.

Machines vary by up to 2x from run to run and other jobs share the cores, so every method is timed in
the same rounds as the baseline, interleaved image by image (a burst of load hits all methods alike),
on the same decoded images (decode excluded), on one core. Times are the thread's CPU time
(``time.thread_time``): compute per image, not the time spent waiting for a core another job holds
(under load, wall-clock times of the same code varied 3x within a minute). Each round gives a
median ms per image per method and its ratio to the baseline's; the table shows the range over the
rounds.

Throughput runs ``station measure --json`` as a user would (start-up included) on the same image
files with ``--jobs 1`` and ``--jobs <cores>``, alternately, several times.
"""

from __future__ import annotations

import contextlib
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

Timed = Callable[[np.ndarray], object]


@dataclass(frozen=True)
class SpeedRow:
    """Per-round median ms per image and ratio to the baseline's median, for one method."""

    method: str
    ms: list[float]
    ratio: list[float]

    def to_json(self) -> dict[str, object]:
        return {
            "ms_per_image": self.ms,
            "ratio_to_baseline": self.ratio,
            "ms_range": [min(self.ms), max(self.ms)],
            "ratio_range": [min(self.ratio), max(self.ratio)],
            "ratio_median": statistics.median(self.ratio),
        }


def time_methods(
    images: Sequence[np.ndarray],
    methods: Mapping[str, Timed],
    *,
    baseline: str,
    failures: tuple[type[Exception], ...],
    rounds: int = 5,
) -> dict[str, SpeedRow]:
    """Time every method on every image, interleaved, ``rounds`` times; a failure (one of ``failures``)
    is timed like a result (the accuracy runs count them)."""
    names = list(methods)
    for image in images[:3]:  # warm caches (lru_caches, allocator, OpenCV's first calls)
        for name in names:
            with contextlib.suppress(*failures):
                methods[name](image)
    per_round: dict[str, list[float]] = {n: [] for n in names}
    for r in range(rounds):
        times: dict[str, list[float]] = {n: [] for n in names}
        for i, image in enumerate(images):
            k = (i + r) % len(names)
            for name in names[k:] + names[:k]:  # rotate the order: no method always runs first
                t0 = time.thread_time()
                with contextlib.suppress(*failures):
                    methods[name](image)
                times[name].append(time.thread_time() - t0)
        for n in names:
            per_round[n].append(1000.0 * float(np.median(times[n])))
    base = per_round[baseline]
    return {
        n: SpeedRow(n, per_round[n], [m / b for m, b in zip(per_round[n], base, strict=True)]) for n in names
    }


@dataclass(frozen=True)
class Throughput:
    """``station measure`` files/s with one job and with ``jobs`` jobs, one entry per repetition."""

    files: int
    jobs: int
    single: list[float]
    parallel: list[float]
    capacity: list[float]

    @property
    def efficiency(self) -> list[float]:
        """files/s(jobs) / (jobs x files/s(1)), pairing each repetition's runs."""
        return [p / (self.jobs * s) for s, p in zip(self.single, self.parallel, strict=True)]

    def to_json(self) -> dict[str, object]:
        return {
            "files": self.files,
            "jobs": self.jobs,
            "files_per_s_jobs_1": self.single,
            "files_per_s_jobs_n": self.parallel,
            "efficiency": self.efficiency,
            "machine_parallel_capacity": self.capacity,
        }


def station_throughput(files: Sequence[Path], *, jobs: int, repeats: int = 3) -> Throughput:
    """Run ``station measure --json`` on ``files`` with --jobs 1 and --jobs ``jobs`` (start-up included)."""
    station = Path(sys.executable).with_name("station")
    cmd = [str(station)] if station.exists() else [sys.executable, "-m", "station.cli"]
    args = [str(f) for f in files]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    single: list[float] = []
    parallel: list[float] = []
    for _ in range(repeats):
        for n, out in ((1, single), (jobs, parallel)):
            t0 = time.perf_counter()
            proc = subprocess.run(
                [*cmd, "measure", "--json", "--jobs", str(n), *args],
                capture_output=True,
                env=env,
                check=False,
            )
            elapsed = time.perf_counter() - t0
            lines = proc.stdout.count(b"\n")
            if proc.returncode not in (0, 1) or lines != len(files):
                raise RuntimeError(
                    f"station measure --jobs {n} failed (exit {proc.returncode}, {lines} lines): "
                    f"{proc.stderr.decode(errors='replace')[-500:]}"
                )
            out.append(len(files) / elapsed)
    return Throughput(len(files), jobs, single, parallel, parallel_capacity(jobs))


_SPIN = "s = 0\nfor i in range(3_000_000):\n    s += i\n"


def parallel_capacity(jobs: int, *, repeats: int = 3) -> list[float]:
    """What the machine gives ``jobs`` processes right now: the time of one fixed CPU-bound Python
    job over that of ``jobs`` copies run at once (1.0: each gets a whole core; other jobs on the
    machine lower it). The throughput target can only be judged where this is near 1."""
    out = []
    for _ in range(repeats):
        times = []
        for n in (1, jobs):
            t0 = time.perf_counter()
            procs = [subprocess.Popen([sys.executable, "-c", _SPIN]) for _ in range(n)]
            for p in procs:
                p.wait()
            times.append(time.perf_counter() - t0)
        out.append(times[0] / times[1])
    return out


def cores() -> int:
    """The cores this process may use (what ``station measure`` uses by default)."""
    return max(1, len(os.sched_getaffinity(0)))
