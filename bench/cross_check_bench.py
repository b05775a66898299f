"""The cross check's cost per frame and its verdicts (issue 19, item 7).

``python -m bench.cross_check_bench [--count N] [--rounds R]``: random poses (the benchmark's envelope,
turned up to 30 deg) rendered with the ``nominal``, ``hard`` and ``hard-specks`` presets; each frame
is measured once in precise mode for its edges, then ``check_single_cross`` alone is timed on it
(``time.thread_time``: the thread's CPU time, not the wait for a core another job holds; the median
per round, the range over rounds), with the compiled kernels and with the numpy reference, beside
the whole of precise mode's ``measure`` on the same frames in the same rounds. Also counts the frames
the check refuses (all of them are whole crosses: every refusal is a false one). Written to
``bench/results/cross_check.json`` too.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2
import numpy as np

from sim.artifact import render
from sim.imageset import random_poses
from station.vision import EDGES, MeasurementError, MeasureParams, check_single_cross, measure
from station.vision._kernels import available, kernels

PRESETS = ("nominal", "hard", "hard-specks")


def _frames(preset: str, count: int) -> list[np.ndarray]:
    poses = random_poses(count, seed=23, max_rotation_deg=30.0)
    return [render(pose, preset=preset, rng=np.random.default_rng(k))[0] for k, pose in enumerate(poses)]


def _check_of(image: np.ndarray) -> Callable[[], None] | None:
    """The cross check of one frame, on the edges precise mode found (None: precise mode refused it
    before the check)."""
    params = MeasureParams(mode="precise")
    try:
        m = measure(image, params)
    except MeasurementError:
        return None
    lines = {e: (float(a), float(b), float(c)) for e, (a, b, c) in zip(EDGES, m.lines, strict=True)}
    corners, widths = np.asarray(m.corners_px), (float(m.groove_width_px[0]), float(m.groove_width_px[1]))

    def run() -> None:
        check_single_cross(image, lines, corners, widths)

    return run


def _measure_of(image: np.ndarray) -> Callable[[], object]:
    """Precise mode's whole measurement of one frame."""

    def run() -> object:
        return measure(image, MeasureParams(mode="precise"))

    return run


def _time(calls: Sequence[Callable[[], object]], rounds: int) -> list[float]:
    """Median ms per call in each round (refusals are timed like results)."""
    out = []
    for _ in range(rounds):
        times = []
        for call in calls:
            t0 = time.thread_time()
            with contextlib.suppress(MeasurementError):
                call()
            times.append(time.thread_time() - t0)
        out.append(1000.0 * statistics.median(times))
    return out


def one(preset: str, count: int, rounds: int) -> dict[str, Any]:
    frames = _frames(preset, count)
    checks = [c for c in (_check_of(f) for f in frames) if c is not None]
    refused: dict[str, int] = {}
    for check in checks:
        try:
            check()
        except MeasurementError as exc:
            refused[exc.code] = refused.get(exc.code, 0) + 1
    whole = [_measure_of(f) for f in frames]
    row: dict[str, Any] = {"frames": len(frames), "checked": len(checks), "refused_by_check": refused}
    for choice in ("c", "numpy") if available() else ("numpy",):
        with kernels(choice):
            _time([*checks[:3], *whole[:3]], 1)  # warm caches
            check_ms: list[float] = []
            measure_ms: list[float] = []
            for _ in range(rounds):  # interleaved: a burst of load hits both alike
                check_ms += _time(checks, 1)
                measure_ms += _time(whole, 1)
        row[choice] = {
            "check_ms": [min(check_ms), max(check_ms)],
            "precise_measure_ms": [min(measure_ms), max(measure_ms)],
            "share": [
                min(c / m for c, m in zip(check_ms, measure_ms, strict=True)),
                max(c / m for c, m in zip(check_ms, measure_ms, strict=True)),
            ],
        }
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.cross_check_bench", description=__doc__)
    parser.add_argument("--count", type=int, default=48, help="frames per preset")
    parser.add_argument("--rounds", type=int, default=5, help="timing rounds (ranges are over these)")
    parser.add_argument("--out", type=Path, default=Path("bench/results/cross_check.json"))
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    results = {p: one(p, args.count, args.rounds) for p in PRESETS}
    print(
        f"{'preset':12} {'kernels':8} {'check ms':>14} {'precise ms':>14} {'share':>12}  refused by the check"
    )
    for preset, row in results.items():
        for choice in ("c", "numpy"):
            if choice not in row:
                continue
            r = row[choice]
            print(
                f"{preset:12} {choice:8} {r['check_ms'][0]:6.3f}-{r['check_ms'][1]:6.3f} "
                f"{r['precise_measure_ms'][0]:6.2f}-{r['precise_measure_ms'][1]:6.2f} "
                f"{r['share'][0]:5.2f}-{r['share'][1]:5.2f}  "
                f"{row['refused_by_check'] or 'none'} of {row['checked']}"
            )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2))
    print(f"\n(written to {args.out})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
