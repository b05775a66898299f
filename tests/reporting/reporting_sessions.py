"""Synthetic but realistic sessions for report tests: seeded Gaussian data through the real metrology.

The validation pattern is the seed's (the perimeter of a 50.8 um square in 5.08 um steps, 40 positions);
measured positions are the commanded ones through a rotation, a scale error of the groove width and a
non-perpendicular table, plus noise; the fits come from ``station.metrology``. Repeatability points are
Gaussian around a barycentre, sized so that RP comes near the seed's Table 2.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from station.metrology import compare_displacements, repeatability

SEED_TABLE_2_MM = {"J1": 0.01664, "J2": 0.01813, "J3": 0.02321, "J4": 0.01671, "J5": 0.05299, "J6": 0.01601}
SEED_SEQUENCES_MM = {"S1": 0.06346, "S2": 0.06939}


def seed_pattern_um() -> np.ndarray:
    """The seed's 40 table positions (um): 10 steps of 5.08 um along each side of the square."""
    step = 5.08
    legs = [(1, 0), (0, 1), (-1, 0), (0, -1)]
    pts, p = [], np.zeros(2)
    for dx, dy in legs:
        for _ in range(10):
            pts.append(p.copy())
            p = p + step * np.array([dx, dy])
    return np.array(pts)


def _header(kind: str, sid: str, state: str = "succeeded") -> dict[str, Any]:
    return {
        "id": sid,
        "kind": kind,
        "state": state,
        "created_at": "2026-11-27T18:30:05+00:00",
        "params": {},
        "identities": {
            "robot": {"model": "CRS A465 / C500C", "port": "/dev/pts/7", "firmware": "C500C 2.45"},
            "camera": {"model": "sim", "serial": "SIM-0001"},
            "table": {"model": "manual X-Y micrometer table", "serial": "XY-1"},
        },
        "software": {"station": "0.1.0", "python": "3.11.7", "numpy": "2.4.6", "host": "bench-1"},
        "results": None,
    }


def validation_results(seed: int = 1, *, noise_um: float = 0.05, scale: float = 1.031) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    cmd = seed_pattern_um()
    theta = math.radians(2.0)
    R = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
    shear = np.array([[1.0, 0.004], [0.0, 1.0]])  # table axes 0.23 deg from perpendicular
    meas = cmd @ (scale * R @ shear).T + np.array([3.0, -1.5]) + rng.normal(0, noise_um, cmd.shape)
    c = compare_displacements(cmd, meas)

    def residuals(f: Any) -> np.ndarray:
        return np.asarray(meas - (cmd @ f.A.T + f.t))

    raw, par = residuals(c.rigid), residuals(c.affine)

    def fit(f: Any) -> dict[str, float]:
        return {"mean_um": f.mean, "max_um": f.max, "rms_um": f.rms, "scale": f.scale}

    return {
        "mean_um": c.rigid.mean,
        "max_um": c.rigid.max,
        "parallelogram_mean_um": c.affine.mean,
        "parallelogram_max_um": c.affine.max,
        "scale": c.similarity.scale,
        "groove_width_mm": 0.794 / c.similarity.scale,
        "rigid": fit(c.rigid),
        "similarity": fit(c.similarity),
        "affine": fit(c.affine),
        "positions": [
            {
                "index": i,
                "commanded_um": cmd[i].tolist(),
                "measured_um": meas[i].tolist(),
                "error_um": raw[i].tolist(),
                "error_parallelogram_um": par[i].tolist(),
            }
            for i in range(len(cmd))
        ],
        "scale_calibration": {
            "groove_width_mm": 0.794 / c.similarity.scale,
            "u_mm": 0.0011,
            "session_id": "v-1",
        },
        "groove_width_u_mm": 0.0011,
        "groove_width_used_mm": 0.794,
        "approach": "same-direction",
        "n_positions": len(cmd),
        "failures": [],
    }


def _bootstrap_rp(points: np.ndarray, rng: np.random.Generator, n: int = 400) -> list[float]:
    idx = rng.integers(0, len(points), size=(n, len(points)))
    samples = points[idx]  # (n, N, 2)
    d = np.linalg.norm(samples - samples.mean(axis=1, keepdims=True), axis=2)
    rp = d.mean(axis=1) + 3 * d.std(axis=1, ddof=1)
    return [float(np.percentile(rp, 2.5)), float(np.percentile(rp, 97.5))]


def repeatability_results(seed: int = 2, *, cycles: int = 30, sequences: bool = True) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    targets = dict(SEED_TABLE_2_MM, **(SEED_SEQUENCES_MM if sequences else {}))
    tests: dict[str, Any] = {}
    for name, seed_rp in targets.items():
        sigma = seed_rp / 3.22  # RP of a round 2-D Gaussian ~ 3.22 sigma
        centre = rng.normal(0, 0.5, 2) + np.array([1.2, -0.4])
        pts = centre + rng.normal(0, sigma, (cycles, 2))
        rep = repeatability(pts)
        test: dict[str, Any] = {
            "points_mm": pts.tolist(),
            "barycentre_mm": list(rep.barycentre),
            "l_bar_mm": rep.l_bar,
            "s_l_mm": rep.s_l,
            "rp_mm": rep.rp,
            "rp_ci95_mm": _bootstrap_rp(pts, rng),
            "n_cycles": cycles,
            "failures": [],
        }
        if name.startswith("J"):
            joint = int(name[1])
            test.update(kind="joint", joint=joint, delta_deg=-10.0 if joint in (2, 3) else 10.0)
        else:
            test.update(kind="sequence", targets_deg=[[0, -30, 100, 0, 20, 0], [15, -20, 90, 10, 30, 45]])
        tests[name] = test
    return {
        "rp_mm": {k: v["rp_mm"] for k, v in tests.items()},
        "n_cycles": cycles,
        "tests": tests,
        "seed_table2_mm": targets,
        "speed_pct": 80,
        "load_kg": 1.0,
    }


def sweep_results(seed: int = 3) -> dict[str, Any]:
    from station.parameter_study import SEED_TABLE_1

    rng = np.random.default_rng(seed)
    trials = []
    for n, f, sk, tw, th, mx, mn in SEED_TABLE_1:
        factor = rng.uniform(0.6, 0.9)
        trial: dict[str, Any] = {
            "number": n,
            "overrides": {"filter": f, "skip": sk, "testwidth": tw, "testheight": th},
            "mean_um": mn * 1000 * factor,
            "max_um": mx * 1000 * factor,
            "error": None,
        }
        if n == 6:
            trial.update(mean_um=None, max_um=None, error="image 12: only 3 of 4 edges found")
        trials.append(trial)
    ok = [t for t in trials if t["mean_um"] is not None]
    best = min(ok, key=lambda t: (round(t["mean_um"], 4), t["max_um"]))["number"]
    return {"trials": trials, "best": best, "source_session": "v-1"}


def session(kind: str, sid: str = "s-0001", **changes: Any) -> dict[str, Any]:
    """A whole session of ``kind`` with results; ``changes`` override header fields."""
    s = _header(kind, sid)
    measure = {"mode": "precise", "groove_width_mm": 0.794, "camera_matrix": None}
    if kind == "validation":
        plan = {"frames_per_position": 1, "approach": "same-direction", "approach_um": 10.0}
        s["results"] = validation_results()
    elif kind == "repeatability":
        plan = {"cycles": 30, "warmup_cycles": 3, "delta_deg": 10, "speed_pct": 80, "load_kg": 1.0}
        s["results"] = repeatability_results()
    elif kind == "sweep":
        plan, measure = {"session": "v-1"}, {"mode": "paper"}
        s["results"] = sweep_results()
    else:
        plan, measure = {"session": "v-1"}, dict(measure, window_sigmas=3.0)
        s["results"] = {
            "source_session": "v-1",
            "kind": "validation",
            "validation": validation_results(seed=4),
        }
    s["params"] = {"plan": plan, "measure": measure, "scale_calibration": None}
    s.update(changes)
    return s
