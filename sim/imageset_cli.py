"""``station sim render-set`` and ``station sim render``: simulated artifact images on disk.

Results (the folder or file written) go to stdout, a one-line summary to stderr. Exit codes: 0 done,
1 the request cannot be carried out (message on stderr), 2 usage error (argparse).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from sim.artifact import ArtifactSpec, CameraSpec, pose_for_center_px, render
from sim.imageset import (
    ImageSetError,
    TableSpec,
    load_truth,
    render_random_set,
    render_validation_set,
)
from sim.presets import PRESETS, get_preset
from sim.ruler_cli import render_ruler_set

__all__ = ["register"]

DEFAULT_RANDOM_COUNT = 48


def register(sim_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``render-set`` and ``render`` to the ``station sim`` sub-parsers."""
    p = sim_sub.add_parser(
        "render-set",
        help="render a simulated image set (validation series or random poses) with truth",
        description="Render a folder of simulated artifact images with truth.json "
        "(and displacements.csv for the validation series, seed section 4).",
    )
    p.add_argument(
        "out_dir", metavar="OUT_DIR", type=Path, help="folder to write (must be empty unless --force)"
    )
    p.add_argument("--pattern", choices=("validation", "random"), default="validation")
    p.add_argument(
        "--artifact",
        choices=("cross", "ruler"),
        default="cross",
        help="the crossed-groove artifact or the ruler",
    )
    p.add_argument(
        "--preset", choices=sorted(PRESETS), default="nominal", help="noise preset (default nominal)"
    )
    p.add_argument(
        "--count", type=int, default=None, help=f"random: number of images ({DEFAULT_RANDOM_COUNT})"
    )
    p.add_argument("--seed", type=int, default=0, help="seed of poses and noise (default 0)")
    p.add_argument(
        "--max-rotation", type=float, default=None, metavar="DEG", help="random: rotation bound (10)"
    )
    p.add_argument("--true-width-mm", type=float, default=None, metavar="W", help="true groove width, mm")
    p.add_argument(
        "--table-rotation-deg", type=float, default=0.0, metavar="A", help="validation: table axes"
    )
    p.add_argument("--table-skew-deg", type=float, default=0.0, metavar="S", help="validation: axes skew")
    p.add_argument(
        "--force", action="store_true", help="overwrite the images and truth of a non-empty folder"
    )
    p.set_defaults(func=_render_set)

    r = sim_sub.add_parser(
        "render",
        help="render one simulated artifact image",
        description="Render one simulated artifact image (8-bit PNG) and optionally its truth as JSON.",
    )
    r.add_argument("out_png", metavar="OUT.png", type=Path)
    r.add_argument("--center-px", type=float, nargs=2, default=None, metavar=("X", "Y"), help="crossing, px")
    r.add_argument("--rotation", type=float, default=0.0, metavar="DEG", help="in-plane rotation, deg")
    r.add_argument("--tilt-x", type=float, default=0.0, metavar="DEG")
    r.add_argument("--tilt-y", type=float, default=0.0, metavar="DEG")
    r.add_argument("--preset", choices=sorted(PRESETS), default="nominal")
    r.add_argument("--seed", type=int, default=0, help="seed of the frame noise (default 0)")
    r.add_argument("--true-width-mm", type=float, default=None, metavar="W", help="true groove width, mm")
    r.add_argument("--truth", type=Path, default=None, metavar="OUT.json", help="also write the truth here")
    r.set_defaults(func=_render_one)


def _fail(message: str) -> int:
    sys.stderr.write(f"station sim: {message}\n")
    return 1


def _artifact(width_mm: float | None) -> ArtifactSpec:
    return ArtifactSpec() if width_mm is None else ArtifactSpec(groove_width_mm=width_mm)


def _render_set(args: argparse.Namespace) -> int:
    if args.artifact == "ruler":
        return render_ruler_set(args)
    start = time.perf_counter()
    try:
        artifact = _artifact(args.true_width_mm)
        if args.pattern == "validation":
            if args.count is not None or args.max_rotation is not None:
                return _fail("--count and --max-rotation apply to --pattern random only")
            table = TableSpec(rotation_deg=args.table_rotation_deg, skew_deg=args.table_skew_deg)
            out = render_validation_set(
                args.out_dir,
                preset=args.preset,
                seed=args.seed,
                table=table,
                artifact=artifact,
                force=args.force,
            )
        else:
            if args.table_rotation_deg or args.table_skew_deg:
                return _fail("--table-rotation-deg and --table-skew-deg apply to --pattern validation only")
            out = render_random_set(
                args.out_dir,
                preset=args.preset,
                count=DEFAULT_RANDOM_COUNT if args.count is None else args.count,
                seed=args.seed,
                max_rotation_deg=10.0 if args.max_rotation is None else args.max_rotation,
                artifact=artifact,
                force=args.force,
            )
        truth = load_truth(out)
    except (ImageSetError, ValueError, OSError) as exc:
        return _fail(str(exc))
    preset = truth.preset
    sys.stderr.write(
        f"station sim: {len(truth.images)} {truth.kind} images, preset {preset.name} v{preset.version}, "
        f"seed {truth.seed}, true width {truth.artifact.groove_width_mm:.4f} mm, "
        f"{time.perf_counter() - start:.1f} s -> {out}\n"
    )
    sys.stdout.write(f"{out}\n")
    return 0


def _render_one(args: argparse.Namespace) -> int:
    try:
        camera = CameraSpec()
        cx, cy = camera.principal_point if args.center_px is None else args.center_px
        pose = pose_for_center_px(
            cx, cy, rotation_deg=args.rotation, tilt_x_deg=args.tilt_x, tilt_y_deg=args.tilt_y, camera=camera
        )
        preset = get_preset(args.preset)
        image, truth = render(
            pose,
            preset=preset,
            artifact=_artifact(args.true_width_mm),
            camera=camera,
            rng=np.random.default_rng(args.seed),
        )
        args.out_png.parent.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(args.out_png), image):
            return _fail(f"could not write {args.out_png} (is the extension .png?)")
        if args.truth is not None:
            doc = {"preset": preset.to_dict(), "seed": args.seed, **truth.to_dict()}
            args.truth.parent.mkdir(parents=True, exist_ok=True)
            args.truth.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    except (ValueError, OSError, cv2.error) as exc:
        return _fail(str(exc))
    sys.stderr.write(
        f"station sim: rendered preset {preset.name} v{preset.version}, centre "
        f"({truth.center_px[0]:.3f}, {truth.center_px[1]:.3f}) px, rotation {args.rotation} deg"
        f" -> {args.out_png}\n"
    )
    sys.stdout.write(f"{args.out_png}\n")
    return 0
