"""Camera calibration on the twin, against its truth (issue 23): ``python -m bench.camcal_bench``.

For each seed, a true camera drawn by ``sim.lens.true_intrinsics`` (focal length +/-2 %, principal point
+/-20 px, radial distortion up to 2 px at the corner; tangential in the ``tangential`` case) sees the
standard target (``station.camcal.STANDARD_TARGET``) in the views a session takes
(``station.camcal.plan_views``: 4 square turns, each in focus once and 26 times at -1.5 and +1.5 mm, read by
the distance sensor beside the camera, the corners followed into the blur from the view in focus; and 16
views tilted 12 deg in 24 directions and 4 turns: 308). Each frame is rendered
(``sim.target``), detected, and the intrinsics calibrated; the result is compared with the truth. Cases,
by the optics' depth of field (the blur's growth away from focus):

* ``in-focus``: no defocus (a lens stopped down so far that the target is sharp at every tilt);
* ``f/4``: 3.1 px/mm, the seed's 1X macro lens at f/4 (``sim.target.F4_DEFOCUS_PX_PER_MM``);
* ``world``: 20 px/mm, the simulated world's setting today;
* ``tangential``: f/4 with a decentred lens (tangential distortion up to 1 px), fitted with p1, p2.

Then the scale check: a crossed-groove capture measured, compared with the camera model at the working
distance, with the right focal length and with 1 % errors either way, against the drawing's width
tolerance and against a scale calibration's. Written to ``bench/results/camcal.json`` too (``--out``).
Rendering takes about 0.1 s of CPU a frame (``bench.target_render_bench``; 0.3-0.5 s before the render's
shortcuts), detection and the fit the rest of each calibration.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from sim.artifact import CameraSpec, pose_for_center_px, render
from sim.lens import nominal_intrinsics, true_intrinsics
from sim.target import (
    F4_DEFOCUS_PX_PER_MM,
    WORLD_DEFOCUS_PX_PER_MM,
    TargetPose,
    render_target,
)
from sim.target_sensor import sensor_distance
from station.camcal import (
    CameraCalibrationError,
    FitOptions,
    SensorReading,
    TargetDetection,
    TargetNotFoundError,
    ViewSpec,
    calibrate_intrinsics,
    check_scale,
    detect_target,
    follow_target,
    plan_views,
)
from station.camera_model import CameraIntrinsics
from station.kinds.camera_calibration.views import FOLLOW_SIGMA_PX
from station.vision import NOMINAL_GROOVE_WIDTH_MM, measure

RESULTS = Path(__file__).resolve().parent / "results" / "camcal.json"
MOUNT = np.eye(4)
MOUNT[:3, 3] = (30.0, 0.0, 0.0)  # the sim station's sensor: 30 mm beside the axis, beam parallel to it

CASES: dict[str, tuple[float, float, FitOptions]] = {  # defocus px/mm, tangential px, fit
    "in-focus": (0.0, 0.0, FitOptions()),
    "f/4": (F4_DEFOCUS_PX_PER_MM, 0.0, FitOptions()),
    "world": (WORLD_DEFOCUS_PX_PER_MM, 0.0, FitOptions()),
    "tangential": (F4_DEFOCUS_PX_PER_MM, 1.0, FitOptions(tangential=True)),
}


def views_for(small: bool) -> list[ViewSpec]:
    if small:
        return plan_views(square_turns_deg=(0.0, 90.0), square_passes=2, azimuths=4)
    return plan_views()


def one(seed: int, case: str, views: list[ViewSpec]) -> dict[str, Any]:
    defocus, tangential, options = CASES[case]
    truth = true_intrinsics(seed, tangential_px=tangential)
    rng = np.random.default_rng([seed, 23])
    detections: list[TargetDetection] = []
    readings: list[SensorReading | None] = []
    pose_only: list[bool] = []
    focus: dict[int, tuple[TargetDetection, Any, float]] = {}  # each square turn's view in focus
    render_s = detect_s = 0.0
    skipped = 0
    for view in views:
        pose = TargetPose.from_view(view)
        t0 = time.process_time()
        image, _ = render_target(pose, intrinsics=truth, defocus_px_per_mm=defocus, rng=rng)
        t1 = time.process_time()
        render_s += t1 - t0
        reading = sensor_distance(pose, MOUNT, rng=rng) if view.tilt_deg == 0.0 else None
        followed = view.tilt_deg == 0.0 and view.group in focus
        try:
            if followed:  # as the session does (station.kinds.camera_calibration.views)
                ref, ref_image, z0 = focus[view.group]
                assert reading is not None
                detection = follow_target(
                    image,
                    ref,
                    ref_image,
                    scale=68.0 / (68.0 + reading - z0),
                    centre_px=(319.5, 239.5),
                    sigma_px=FOLLOW_SIGMA_PX,
                )
            else:
                detection = detect_target(image)
        except TargetNotFoundError:
            skipped += 1
            continue
        finally:
            detect_s += time.process_time() - t1
        if view.tilt_deg == 0.0 and not followed:
            assert reading is not None
            focus[view.group] = (detection, image, reading)
        detections.append(detection)
        pose_only.append(followed)
        readings.append(None if reading is None else SensorReading(view.group, reading))
    out: dict[str, Any] = {
        "seed": seed,
        "case": case,
        "views": len(views),
        "skipped": skipped,
        "render_s_per_view": render_s / len(views),
        "detect_s_per_view": detect_s / len(views),
    }
    t0 = time.process_time()
    try:
        cal = calibrate_intrinsics(
            detections, guess=nominal_intrinsics(), readings=readings, options=options, pose_only=pose_only
        )
    except CameraCalibrationError as exc:
        out["error"] = str(exc)
        try:  # what the tilted views alone would have claimed
            alone = calibrate_intrinsics(
                detections, guess=nominal_intrinsics(), options=options, pose_only=pose_only
            )
        except CameraCalibrationError as again:
            return {**out, "tilted_only_error": str(again)}
        K = truth.camera_matrix
        return {
            **out,
            "tilted_only_fx_err_pct": 100 * (alone.intrinsics.fx / K[0, 0] - 1),
            "tilted_only_fx_sigma_pct": 100 * alone.focal.tilted_u_rel,
        }
    out["fit_s"] = time.process_time() - t0
    m, K = cal.intrinsics, truth.camera_matrix
    sig = m.sigma
    out |= {
        "corners": cal.corners,
        "rms_px": cal.rms_px,
        "fx_err_pct": 100 * (m.fx / K[0, 0] - 1),
        "fy_err_pct": 100 * (m.fy / K[1, 1] - 1),
        "fx_sigma_pct": 100 * sig["fx"] / m.fx,
        "cx_err_px": m.principal_point[0] - K[0, 2],
        "cy_err_px": m.principal_point[1] - K[1, 2],
        "cx_sigma_px": sig["cx"],
        "cy_sigma_px": sig["cy"],
        "tilted_fx_err_pct": 100 * (cal.focal.tilted_fx_px / K[0, 0] - 1),
        "tilted_fx_sigma_pct": 100 * cal.focal.tilted_u_rel,
        "disagreement_sigma": cal.focal.disagreement_sigma,
        "problems": cal.problems(),
        "warnings": cal.warnings(),
    }
    return out


def scale_check_rows() -> list[dict[str, Any]]:
    """The scale check on a crossed-groove capture at the working distance (ideal pinhole: CameraSpec)."""
    camera = CameraSpec()
    image, _ = render(pose_for_center_px(330.0, 250.0, rotation_deg=4.0), rng=np.random.default_rng(5))
    m = measure(image)
    rows = []
    for error in (0.0, 0.01, -0.01):
        K = camera.matrix() * np.array([[1 + error, 1, 1], [1, 1 + error, 1], [1, 1, 1]])
        model = CameraIntrinsics(K, np.zeros(5), (camera.width, camera.height), sigma={"fx": 0.5, "fy": 0.5})
        for tolerance, label in (
            ((-0.0508, 0.0), "drawing +0/-0.002 in"),
            ((-0.004, 0.004), "scale cal. +/-4 um"),
        ):
            check = check_scale(
                model,
                distance_mm=camera.working_distance_mm,
                groove_width_px=m.groove_width_px,
                groove_width_mm=NOMINAL_GROOVE_WIDTH_MM,
                width_tolerance_mm=tolerance,
                rotation_deg=m.rotation_deg,
                center_px=m.center_px,
            )
            rows.append(
                {
                    "focal_error_pct": 100 * error,
                    "width": label,
                    "disagreement_pct": 100 * check.disagreement,
                    "passes": check.passes(),
                }
            )
    return rows


def _fmt(r: dict[str, Any]) -> str:
    head = f"{r['case']:>10} seed {r['seed']}:"
    if "error" in r:
        alone = (
            f"; tilted views alone: fx {r['tilted_only_fx_err_pct']:+.3f} % "
            f"(sigma {r['tilted_only_fx_sigma_pct']:.3f})"
            if "tilted_only_fx_err_pct" in r
            else ""
        )
        return f"{head} {r['views'] - r['skipped']}/{r['views']} views found; {r['error']}{alone}"
    parts = [
        f"{r['views'] - r['skipped']}/{r['views']} views, {r['corners']} corners, rms {r['rms_px']:.4f} px",
        f"fx {r['fx_err_pct']:+.4f} % (sigma {r['fx_sigma_pct']:.4f}), fy {r['fy_err_pct']:+.4f} %",
        f"cx {r['cx_err_px']:+.2f} cy {r['cy_err_px']:+.2f} px "
        f"(sigma {r['cx_sigma_px']:.2f}, {r['cy_sigma_px']:.2f})",
        f"tilted fx {r['tilted_fx_err_pct']:+.3f} % (sigma {r['tilted_fx_sigma_pct']:.3f})",
        f"{len(r['problems'])} problems, {len(r['warnings'])} warnings",
        f"render {r['render_s_per_view']:.2f}, detect {r['detect_s_per_view']:.2f} s/view (CPU), "
        f"fit {r['fit_s']:.1f} s",
    ]
    return f"{head} " + " | ".join(parts)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3, help="true cameras per case (default 3)")
    parser.add_argument("--cases", default=",".join(CASES), help=f"comma-separated, of: {', '.join(CASES)}")
    parser.add_argument("--small", action="store_true", help="26 views instead of 308 (a quick check)")
    parser.add_argument("--out", type=Path, default=RESULTS, help=f"JSON results (default {RESULTS.name})")
    args = parser.parse_args(argv)
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = sorted(set(cases) - set(CASES))
    if unknown or args.seeds < 1:
        parser.error(f"unknown cases {unknown} or seeds < 1")
    views = views_for(args.small)
    print(f"camera calibration on the twin: {len(views)} views per calibration, seeds 1-{args.seeds}")
    rows = []
    for case in cases:
        for seed in range(1, args.seeds + 1):
            rows.append(one(seed, case, views))
            print(_fmt(rows[-1]), flush=True)
    for case in cases:
        done = [r for r in rows if r["case"] == case and "error" not in r]
        if done:
            f = max(max(abs(r["fx_err_pct"]), abs(r["fy_err_pct"])) for r in done)
            c = max(max(abs(r["cx_err_px"]), abs(r["cy_err_px"])) for r in done)
            t = max(abs(r["tilted_fx_err_pct"]) for r in done)
            print(
                f"{case:>10}: worst focal {f:.4f} %, principal point {c:.2f} px; tilted views alone {t:.3f} %"
            )
    print("scale check (a 640x480 capture at 68 mm, width 0.794 mm):")
    checks = scale_check_rows()
    for c in checks:
        verdict = "passes" if c["passes"] else "FAILS"
        print(
            f"  focal {c['focal_error_pct']:+.0f} %, {c['width']}: {c['disagreement_pct']:+.3f} % {verdict}"
        )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(
        json.dumps({"views": len(views), "calibrations": rows, "scale_check": checks}, indent=1)
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
