"""The identification on synthetic sessions (``sim.calibration_sessions``) over many seeds.

``python -m bench.calibration_bench [--seeds N]``: for each seed, a true arm drawn like the simulated
station's, the rich pose set (4 placements x 4 turns x the IK's solutions, 2 in-view motions each, 5 um
noise), a quarter of the configurations held out. Reports, per seed and over all: the share of
identified parameters whose 95 % interval holds the truth (``equivalent_errors``), the largest error
in sigmas, the relative error before / after / floor (um), the fit's time. Written to
``bench/results/calibration.json`` too.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from sim import calibration_sessions as synthetic
from station.calibration import (
    CalibrationModel,
    identify,
    relative_error_um,
    true_values,
)
from station.kinematics import A465_DH, Kinematics


def one(seed: int) -> dict[str, float]:
    truth = synthetic.make_truth(seed)
    observations = synthetic.session(truth, seed=seed + 1)
    configurations = sorted({o.configuration for o in observations})
    holdout = configurations[1::4]
    setup = synthetic.setup_for()
    start = time.perf_counter()
    result = identify(observations, setup, holdout=holdout)
    seconds = time.perf_counter() - start
    model = CalibrationModel(setup)
    artifacts = {k: (truth.points[k], truth.normals[k]) for k in truth.points}
    true = true_values(model, truth.kinematics.dh, truth.kinematics.tool, artifacts)
    z = np.array([(p.estimate - true[p.name]) / p.sigma for p in result.parameters if p.sigma])
    held = [o for o in observations if o.configuration in set(holdout)]
    args = (synthetic.CAMERA, synthetic.MOUNT)
    return {
        "seed": seed,
        "observations": len(observations),
        "identified": result.identified_count,
        "inside_95": float(np.mean(np.abs(z) <= 1.97)),
        "max_sigma": float(np.max(np.abs(z))),
        "before_um": relative_error_um(held, Kinematics(A465_DH, tool=synthetic.NOMINAL_TOOL), *args),
        "after_um": relative_error_um(held, result, *args),
        "floor_um": relative_error_um(held, truth.kinematics, *args),
        "fit_s": seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    rows = [one(seed) for seed in range(args.seeds)]
    print(f"{'seed':>4} {'in95':>5} {'max z':>6} {'before':>7} {'after':>6} {'floor':>6} {'fit s':>6}")
    for r in rows:
        print(
            f"{r['seed']:4d} {r['inside_95']:5.2f} {r['max_sigma']:6.2f} {r['before_um']:7.0f}"
            f" {r['after_um']:6.1f} {r['floor_um']:6.1f} {r['fit_s']:6.2f}"
        )
    summary = {
        "seeds": args.seeds,
        "mean_inside_95": float(np.mean([r["inside_95"] for r in rows])),
        "seeds_with_90pct_inside": sum(r["inside_95"] >= 0.9 for r in rows),
        "seeds_within_4_sigma": sum(r["max_sigma"] < 4.0 for r in rows),
        "after_over_floor_max": float(max(r["after_um"] / r["floor_um"] for r in rows)),
        "before_over_after_min": float(min(r["before_um"] / r["after_um"] for r in rows)),
        "fit_s_mean": float(np.mean([r["fit_s"] for r in rows])),
    }
    print(json.dumps(summary, indent=2))
    out = Path(__file__).parent / "results" / "calibration.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"summary": summary, "runs": rows}, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
