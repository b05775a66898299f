"""A frame of the camera-calibration target as a session renders it: ``python -m bench.target_render_bench``.

The twin's camera (``sim.target.render_target``, through ``sim.lens.true_intrinsics`` of seed 3, the
``nominal`` preset, f/4 defocus: ``sim.world``'s defaults) renders the standard target in the default
session's views (``station.camcal.plan_views``: square turns in focus and at -1.5 / +1.5 mm, views tilted
12 deg), a sample of them in turn. Reported: CPU ms per frame (``time.process_time``, OpenCV's threads
included) by kind of view, the first frame apart (it inverts the lens over the image, which later frames
of the same camera reuse), and what the 308 frames of a default session cost. By default the process's
allocator is left as pytest leaves it (the sessions' tests); ``--tuned`` sets it as the station's command
line does (``station.runtime.tune_allocator``). Issue: the test suite's time (the day-one and
camera-calibration tests render about 308 such frames each); main before the render's shortcuts took
about 325 ms a frame here (210 tuned), interleaved with the new render on the same views.
Written to ``bench/results/target_render.json`` too (``--out``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from sim.lens import true_intrinsics
from sim.target import F4_DEFOCUS_PX_PER_MM, TargetPose, render_target
from station.camcal import ViewSpec, plan_views
from station.runtime import tune_allocator

RESULTS = Path(__file__).resolve().parent / "results" / "target_render.json"
SEED = 3


def kind(view: ViewSpec) -> str:
    """The view's kind: what sets the work of its frame (the blur's levels, the lines' slant)."""
    if view.tilt_deg > 0.0:
        return "tilted"
    return "square in focus" if view.height_mm == 0.0 else "square defocused"


def frame_ms(view: ViewSpec, seed: int, rng: np.random.Generator) -> float:
    """CPU ms of one frame of ``view`` through the true camera of ``seed``."""
    lens = true_intrinsics(seed)
    pose = TargetPose.from_view(view)
    t0 = time.process_time()
    render_target(pose, intrinsics=lens, defocus_px_per_mm=F4_DEFOCUS_PX_PER_MM, rng=rng)
    return 1e3 * (time.process_time() - t0)


def run(frames: int, rounds: int) -> dict[str, Any]:
    views = plan_views()
    sample = views[:: max(1, len(views) // frames)][:frames]
    rng = np.random.default_rng(23)
    first = frame_ms(views[0], SEED, rng)  # the lens inverted over the image: once per camera
    by_kind: dict[str, list[float]] = {}
    for _ in range(rounds):
        for view in sample:
            by_kind.setdefault(kind(view), []).append(frame_ms(view, SEED, rng))
    every = [ms for times in by_kind.values() for ms in times]
    share = {k: sum(kind(v) == k for v in views) / len(views) for k in by_kind}
    per_frame = sum(share[k] * statistics.mean(times) for k, times in by_kind.items())
    return {
        "seed": SEED,
        "frames": len(every),
        "first_frame_ms": first,
        "ms_per_frame": {k: statistics.mean(times) for k, times in by_kind.items()},
        "median_ms_per_frame": statistics.median(every),
        "session_frames": len(views),
        "session_render_s": (first + (len(views) - 1) * per_frame) / 1e3,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=24, help="views of the session sampled (default 24)")
    parser.add_argument("--rounds", type=int, default=2, help="times each is rendered (default 2)")
    parser.add_argument("--tuned", action="store_true", help="the station CLI's allocator setting")
    parser.add_argument("--out", type=Path, default=RESULTS, help=f"JSON results (default {RESULTS.name})")
    args = parser.parse_args(argv)
    if args.frames < 1 or args.rounds < 1:
        parser.error("--frames and --rounds must be >= 1")
    tuned = tune_allocator() if args.tuned else False
    r = run(args.frames, args.rounds) | {"allocator_tuned": tuned}
    print(f"target frame, 640 x 480, seed {r['seed']}, f/4 ({'tuned' if tuned else 'default'} allocator):")
    print(f"  first frame (lens inverted): {r['first_frame_ms']:.0f} ms CPU")
    for name, ms in r["ms_per_frame"].items():
        print(f"  {name:>17}: {ms:.0f} ms CPU per frame")
    print(f"  median {r['median_ms_per_frame']:.0f} ms over {r['frames']} frames")
    print(f"  a default session's {r['session_frames']} frames: {r['session_render_s']:.1f} s CPU")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(r, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
