"""``python -m bench.ruler_bench``: the ruler measurement's accuracy, refusals, noise limit and speed.

Issue 22's targets, on ruler sets rendered by the twin (``sim.ruler_imageset``: random views drawn
uniformly inside the measurement's envelope, ``--count`` per preset):

* position error under the origin pixel, nominal: mean <= 0.002 px, max <= 0.006 px; hard: mean
  <= 0.01 px (1 px = 10 um on the simulated camera); with a camera model (under the principal
  point) beside it;
* the code read on 100 % of the views inside the envelope; every view outside it refused with its
  own code (a fixed list of such views: the pattern cut by the frame, a ruler's end, a short
  stretch across a corner, no ruler, a blotted code track, another ruler's code, a mirror image);
* the Cramer-Rao bound of the position under the origin pixel (numerical Fisher information of the
  twin's exact rendering over the pose, grey levels and noise), beside the measured error;
* the scatter of the position over repeated frames of one view (the same pose, ``--repeats`` noise
  draws of the preset) beside that view's Cramer-Rao bound: the noise limit against the noise
  measured, with no error of the pose or the ruler's defects in it; and beside both the closed
  form of ``station.vision._ruler_bound`` (the graduations' edges alone: contrast, blur, noise,
  graduations in view);
* time per 640x480 frame with the compiled kernels (decode excluded), target <= 2 ms, and with the
  numpy reference: wall clock (``perf_counter``, minimum and median over every frame of every
  round) and the process's CPU time (median; less disturbed by other work on a shared machine).

Written to ``bench/results/ruler_bench.json`` too.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import os
import statistics
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2
import numpy as np

from sim._render_camera import CameraSpec, Pose, pose_for_center_px
from sim.artifact import render
from sim.presets import get_preset
from sim.ruler import RulerTruth, render_ruler, ruler_coverage, ruler_truth
from sim.ruler_imageset import load_ruler_truth, render_ruler_random_set
from station.vision import MeasurementError, RulerCode, RulerParams, RulerSpec, measure_ruler
from station.vision._kernels import compiled, kernels
from station.vision._ruler_bound import ruler_view_bound_px

UM_PER_PX = 10.0
TARGETS = {"nominal": {"mean": 0.002, "max": 0.006}, "hard": {"mean": 0.01}}
SPEED_TARGET_MS = 2.0


def _errors(m: Any, truth: RulerTruth, principal: bool) -> tuple[float, float, float]:
    position = truth.principal_position_mm if principal else truth.position_mm
    offset = truth.principal_offset_mm if principal else truth.offset_mm
    return (
        (m.position_mm - position) * truth.px_per_mm,
        (m.offset_mm - offset) * truth.px_per_mm,
        (m.angle_deg - truth.angle_deg + 180.0) % 360.0 - 180.0,
    )


def accuracy(set_dir: Path) -> dict[str, Any]:
    """Measure every image of a ruler set, without and with the camera model, against its truth."""
    header, images = load_ruler_truth(set_dir)
    camera = CameraSpec(**header["camera"])
    with_model = RulerParams(camera_matrix=camera.matrix().tolist(), dist_coeffs=[0.0] * 5)
    rows: dict[str, list[tuple[float, float, float]]] = {"origin": [], "principal": []}
    failures: list[dict[str, str]] = []
    read: list[int] = []
    stated: list[float] = []
    for name, truth in images:
        image = _read(set_dir / name)
        for key, params in (("origin", RulerParams()), ("principal", with_model)):
            try:
                m = measure_ruler(image, params)
            except MeasurementError as exc:
                failures.append({"file": name, "reference": key, "code": exc.code, "error": exc.message})
                continue
            rows[key].append(_errors(m, truth, key == "principal"))
            if key == "origin":
                read.append(m.code.read)
                stated.append(m.extra["position_u_nm"] * 1e-6 * truth.px_per_mm)
    out: dict[str, Any] = {
        "images": len(images),
        "failures": failures,
        "cells_read_min": min(read, default=0),
    }
    for key, errs in rows.items():
        a = np.abs(np.array(errs)).reshape(-1, 3)
        out[key] = {
            "measured": len(errs),
            "position_px": {
                "mean": float(a[:, 0].mean()),
                "max": float(a[:, 0].max()),
                "rms": float(np.sqrt((a[:, 0] ** 2).mean())),
            },
            "offset_px": {"mean": float(a[:, 1].mean()), "max": float(a[:, 1].max())},
            "angle_deg": {"mean": float(a[:, 2].mean()), "max": float(a[:, 2].max())},
        }
    out["origin"]["stated_u_px_median"] = float(np.median(stated)) if stated else math.nan
    return out


def _outside_views() -> list[tuple[str, np.ndarray, str, RulerParams | None]]:
    """Views outside the envelope, each with the code its refusal must carry."""
    rng = np.random.default_rng(77)
    views: list[tuple[str, np.ndarray, str, RulerParams | None]] = []
    for label, (cx, cy, rot, anchor) in {
        "pattern cut at the top": (320, 70, 0.0, 90.0),
        "pattern cut at the side": (590, 240, 90.0, 120.0),
        "pattern cut, turned": (120, 380, 30.0, 60.0),
    }.items():
        views.append(
            (
                label,
                render_ruler(pose_for_center_px(cx, cy, rotation_deg=rot), anchor_mm=anchor, rng=rng)[0],
                "off_ruler",
                None,
            )
        )
    for label, (cx, cy, rot, anchor) in {
        "graduation 0 at x = 410": (560, 240, 0.0, 1.5),
        "graduation 500 at x = 260": (110, 240, 0.0, 248.0),
        "across a corner": (130, 130, -45.0, 50.0),
    }.items():
        image = render_ruler(pose_for_center_px(cx, cy, rotation_deg=rot), anchor_mm=anchor, rng=rng)[0]
        views.append((label, image, "too_few_graduations", None))
    views.append(("no ruler: noise", rng.integers(0, 256, (480, 640), dtype=np.uint8), "off_ruler", None))
    views.append(
        (
            "no ruler: the cross",
            render(pose_for_center_px(320, 240, rotation_deg=5.0), rng=rng)[0],
            "off_ruler",
            None,
        )
    )
    pose = pose_for_center_px(320, 240, rotation_deg=8.0)
    image, truth = render_ruler(pose, anchor_mm=70.0, rng=rng)
    h_inv = np.linalg.inv(truth.homography)
    ys, xs = np.mgrid[0:480, 0:640]
    p = h_inv @ np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
    t = (p[1] / p[2]).reshape(480, 640)
    blotted = image.copy()
    blotted[(t > -0.13) & (t < 0.53)] = 122
    views.append(("code track blotted", blotted, "code_unreadable", None))
    other = RulerParams(ruler=RulerSpec(name="other", code=RulerCode(taps=(11, 2))))
    views.append(("another ruler's code", image, "code_inconsistent", other))
    views.append(("mirror image", np.ascontiguousarray(image[:, ::-1]), "code_inconsistent", None))
    return views


def refusals() -> list[dict[str, Any]]:
    """Each outside view: refused with its own code, or not."""
    out = []
    for label, image, expected, params in _outside_views():
        try:
            m = measure_ruler(image, params)
            got, message = "measured", f"position {m.position_mm:.6f} mm"
        except MeasurementError as exc:
            got, message = exc.code, exc.message
        out.append(
            {"view": label, "expected": expected, "got": got, "ok": got == expected, "message": message}
        )
    return out


def crb_position_px(pose: Pose, anchor_mm: float, preset_name: str) -> tuple[float, float]:
    """Cramer-Rao bound of the position under the origin pixel and under the principal point (px, 1 sigma).

    The twin's exact rendering (``ruler_coverage``) differentiated numerically over the pose (six
    parameters) and the two grey levels; the noise of the preset (read and shot, quantisation) per
    pixel. Vignetting, the illumination gradient and the defects are left out: the bound is the
    pattern's own.
    """
    p = get_preset(preset_name)
    names = ["x_mm", "y_mm", "rotation_deg", "tilt_x_deg", "tilt_y_deg", "z_mm"]
    steps = [1e-4, 1e-4, 1e-3, 1e-3, 1e-3, 1e-4]
    cover = ruler_coverage(pose, anchor_mm=anchor_mm, blur_sigma_px=p.blur_sigma_px)
    contrast = p.paint_level_dn - p.land_level_dn
    mean = p.land_level_dn + cover * contrast
    variance = (p.read_noise_dn**2 + p.shot_noise_gain_dn_per_e * mean + 1.0 / 12.0).ravel()
    columns, grad_o, grad_p = [], [], []
    for name, h in zip(names, steps, strict=True):
        plus = dataclasses.replace(pose, **{name: getattr(pose, name) + h})
        minus = dataclasses.replace(pose, **{name: getattr(pose, name) - h})
        d = ruler_coverage(plus, anchor_mm=anchor_mm, blur_sigma_px=p.blur_sigma_px) - ruler_coverage(
            minus, anchor_mm=anchor_mm, blur_sigma_px=p.blur_sigma_px
        )
        columns.append((d * contrast / (2 * h)).ravel())
        tp, tm = ruler_truth(plus, anchor_mm=anchor_mm), ruler_truth(minus, anchor_mm=anchor_mm)
        grad_o.append((tp.position_mm - tm.position_mm) / (2 * h))
        grad_p.append((tp.principal_position_mm - tm.principal_position_mm) / (2 * h))
    columns += [np.ones(mean.size), cover.ravel()]
    grad_o += [0.0, 0.0]
    grad_p += [0.0, 0.0]
    jac = np.array(columns).T
    fisher_inv = np.linalg.inv(jac.T @ (jac / variance[:, None]))
    scale = ruler_truth(pose, anchor_mm=anchor_mm).px_per_mm
    go, gp = np.array(grad_o), np.array(grad_p)
    return float(np.sqrt(go @ fisher_inv @ go)) * scale, float(np.sqrt(gp @ fisher_inv @ gp)) * scale


def speed(set_dir: Path, rounds: int) -> dict[str, Any]:
    """Milliseconds per frame (decode excluded), compiled kernels and numpy reference: wall clock
    (``perf_counter``) minimum and median, process CPU time median, over ``rounds`` passes over the
    set's frames."""
    _, images = load_ruler_truth(set_dir)
    frames = [_read(set_dir / name) for name, _ in images]
    out: dict[str, Any] = {}
    for choice in ("c", "numpy"):
        if choice == "c" and compiled() is None:
            continue
        with kernels(choice):
            for frame in frames[:2]:
                _try(frame)
            wall, cpu = [], []
            for _ in range(rounds):
                for frame in frames:
                    t0, c0 = time.perf_counter(), time.process_time()
                    _try(frame)
                    wall.append((time.perf_counter() - t0) * 1000.0)
                    cpu.append((time.process_time() - c0) * 1000.0)
        out[choice] = {
            "frames": len(wall),
            "wall_ms_min": min(wall),
            "wall_ms_median": statistics.median(wall),
            "cpu_ms_median": statistics.median(cpu),
        }
    return out


def noise_scatter(
    pose: Pose, anchor_mm: float, preset: str, repeats: int, *, seed: int = 100
) -> dict[str, Any]:
    """One view rendered ``repeats`` times with fresh noise (the same pose, light and defects): the
    standard deviation of the measured position about its mean, under the origin pixel and under the
    principal point (px), beside that view's Cramer-Rao bound (``crb_position_px``), and the mean
    error against the truth (the view's own bias, outside the scatter)."""
    camera = CameraSpec()
    with_model = RulerParams(camera_matrix=camera.matrix().tolist(), dist_coeffs=[0.0] * 5)
    errors: dict[str, list[float]] = {"origin": [], "principal": []}
    periods: list[float] = []
    for k in range(repeats):
        image, truth = render_ruler(
            pose, anchor_mm=anchor_mm, preset=preset, rng=np.random.default_rng(seed + k)
        )
        for key, params in (("origin", RulerParams()), ("principal", with_model)):
            m = measure_ruler(image, params)
            errors[key].append(_errors(m, truth, key == "principal")[0])
            periods.append(float(m.extra["periods_in_view"]))
    bound = dict(zip(("origin", "principal"), crb_position_px(pose, anchor_mm, preset), strict=True))
    out: dict[str, Any] = {"repeats": repeats, "preset": preset}
    for key, errs in errors.items():
        scatter = float(np.std(errs, ddof=1))
        out[key] = {
            "scatter_px": scatter,
            "crb_px": bound[key],
            "ratio": scatter / bound[key],
            "mean_error_px": float(np.mean(errs)),
        }
    # the sample standard deviation's own relative uncertainty (chi distribution, repeats - 1 dof)
    out["scatter_relative_u"] = 1.0 / math.sqrt(2.0 * (repeats - 1))
    out["closed_form_px"] = closed_form_bound_px(preset, truth.px_per_mm, float(np.median(periods)))
    return out


def closed_form_bound_px(preset: str, px_per_mm: float, periods_in_view: float) -> float:
    """``station.vision``'s closed-form bound (the graduations' edges alone, everything else known)
    for the preset's contrast, blur and noise (read, shot at the mid grey level, quantisation)."""
    p = get_preset(preset)
    mid = 0.5 * (p.land_level_dn + p.paint_level_dn)
    noise = math.sqrt(p.read_noise_dn**2 + p.shot_noise_gain_dn_per_e * mid + 1.0 / 12.0)
    spec = RulerSpec()
    return ruler_view_bound_px(
        spec,
        px_per_mm=px_per_mm,
        graduated_mm=periods_in_view * spec.pitch_mm,
        contrast_dn=p.land_level_dn - p.paint_level_dn,
        noise_dn=noise,
        blur_sigma_px=p.blur_sigma_px,
    )


#: The views of the repeatability figures: (centre x, centre y, rotation, tilt x, tilt y, anchor).
SCATTER_VIEWS = ((320.0, 240.0, 7.0, 0.3, -0.2, 40.0), (300.0, 250.0, -100.0, -0.5, 0.4, 123.4))


def _read(path: Path) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise FileNotFoundError(f"{path}: not readable")
    return np.asarray(image)


def _try(frame: np.ndarray) -> None:
    with contextlib.suppress(MeasurementError):
        measure_ruler(frame)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=48, help="random views per preset (48)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--crb-views", type=int, default=6, help="views per preset for the bound (6)")
    parser.add_argument("--rounds", type=int, default=5, help="timing rounds (5)")
    parser.add_argument("--repeats", type=int, default=24, help="noise draws per view for the scatter (24)")
    parser.add_argument("--data", type=Path, default=Path("bench/results/ruler-data"))
    parser.add_argument("--out", type=Path, default=Path("bench/results/ruler_bench.json"))
    args = parser.parse_args(argv)
    results: dict[str, Any] = {"um_per_px": UM_PER_PX, "count": args.count, "seed": args.seed, "presets": {}}
    for preset in ("nominal", "hard"):
        set_dir = args.data / f"{preset}-random-{args.count}-{args.seed}"
        if not (set_dir / "truth.json").exists():
            render_ruler_random_set(set_dir, preset=preset, count=args.count, seed=args.seed, force=True)
        entry = accuracy(set_dir)
        _, images = load_ruler_truth(set_dir)
        bounds = [crb_position_px(t.pose, t.anchor_mm, preset) for _, t in images[: args.crb_views]]
        entry["crb_px"] = {
            "origin_sigma_mean": float(np.mean([b[0] for b in bounds])),
            "principal_sigma_mean": float(np.mean([b[1] for b in bounds])),
            "origin_expected_mean_abs": float(np.mean([b[0] for b in bounds]) * math.sqrt(2 / math.pi)),
            "views": len(bounds),
        }
        entry["scatter"] = [
            noise_scatter(
                pose_for_center_px(x, y, rotation_deg=rot, tilt_x_deg=tx, tilt_y_deg=ty),
                anchor,
                preset,
                args.repeats,
            )
            for x, y, rot, tx, ty, anchor in SCATTER_VIEWS
        ]
        if preset == "nominal":
            entry["speed"] = speed(set_dir, args.rounds)
        results["presets"][preset] = entry
    results["refusals"] = refusals()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print(report_text(results))
    return 0


def report_text(results: dict[str, Any]) -> str:
    """The figures as text, each beside its target."""
    lines = [
        f"ruler measurement, {results['count']} random views per preset inside the envelope (1 px = 10 um)"
    ]
    head = (
        f"{'preset':8} {'reference':10} {'measured':>9} {'position mean/max (px)':>24} "
        f"{'offset mean/max (px)':>22} {'angle max (deg)':>16} {'CRB mean|err| (px)':>19}"
    )
    lines += [head, "-" * len(head)]
    for preset, entry in results["presets"].items():
        for key in ("origin", "principal"):
            e = entry[key]
            crb = entry["crb_px"]["origin_expected_mean_abs" if key == "origin" else "principal_sigma_mean"]
            if key == "principal":
                crb *= math.sqrt(2 / math.pi)
            lines.append(
                f"{preset:8} {key:10} {e['measured']:>4}/{entry['images']:<4} "
                f"{e['position_px']['mean']:>11.5f} / {e['position_px']['max']:.5f} "
                f"{e['offset_px']['mean']:>11.4f} / {e['offset_px']['max']:.4f} "
                f"{e['angle_deg']['max']:>16.4f} {crb:>19.5f}"
            )
        target = TARGETS[preset]
        e = entry["origin"]["position_px"]
        verdicts = [f"mean {e['mean']:.5f} {'<=' if e['mean'] <= target['mean'] else '>'} {target['mean']}"]
        if "max" in target:
            verdicts.append(
                f"max {e['max']:.5f} {'<=' if e['max'] <= target['max'] else '>'} {target['max']}"
            )
        read = entry["origin"]["measured"] == entry["images"]
        verdicts.append(
            f"code read on {entry['origin']['measured']}/{entry['images']} ({'met' if read else 'MISSED'})"
        )
        lines.append(f"  target ({preset}): " + ", ".join(verdicts))
        for view in entry.get("scatter", []):
            o, p = view["origin"], view["principal"]
            lines.append(
                f"  scatter over {view['repeats']} noise draws of one view (px, 1 sigma; +/-"
                f"{100 * view['scatter_relative_u']:.0f} %): origin {o['scatter_px']:.5f} vs Cramer-Rao "
                f"{o['crb_px']:.5f} ({o['ratio']:.2f}x), principal point {p['scatter_px']:.5f} vs "
                f"{p['crb_px']:.5f} ({p['ratio']:.2f}x); closed form, edges alone: "
                f"{view['closed_form_px']:.5f}"
            )
        if "speed" in entry:
            for choice, s in entry["speed"].items():
                verdict = "met" if s["wall_ms_median"] <= SPEED_TARGET_MS else "missed"
                note = f" (target <= {SPEED_TARGET_MS} ms: {verdict})" if choice == "c" else ""
                which = "compiled kernels" if choice == "c" else "numpy reference"
                lines.append(
                    f"  time per frame, {which}: wall median {s['wall_ms_median']:.2f} ms (min "
                    f"{s['wall_ms_min']:.2f}), CPU median {s['cpu_ms_median']:.2f} ms over {s['frames']} "
                    f"frames{note}"
                )
    refused = results["refusals"]
    lines.append(
        f"views outside the envelope refused with their code: {sum(r['ok'] for r in refused)}/{len(refused)}"
    )
    lines += [
        f"  {r['view']}: {r['got']}{'' if r['ok'] else ' (expected ' + r['expected'] + ')'}" for r in refused
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
