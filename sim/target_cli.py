"""``station sim render-target``: one frame of the camera-calibration target through the twin's true lens.

The file written goes to stdout, a one-line summary to stderr. Exit codes: 0 done, 1 the request cannot
be carried out (message on stderr), 2 usage error (argparse).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

from sim.lens import true_intrinsics
from sim.presets import PRESETS, get_preset
from sim.target import F4_DEFOCUS_PX_PER_MM, TargetPose, render_target
from station.camcal import STANDARD_TARGET, ViewSpec

__all__ = ["register"]


def register(sim_sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``render-target`` to the ``station sim`` sub-parsers."""
    p = sim_sub.add_parser(
        "render-target",
        help="render the camera-calibration target through the twin's true lens, with truth",
        description="Render one 8-bit frame of the standard ChArUco target (station/camcal/TARGET.md) seen "
        "through a true lens drawn from --lens-seed, the camera moved from the square pose as a "
        "calibration's view is (tilt about the in-focus point, turn, height).",
    )
    p.add_argument("out_png", metavar="OUT.png", type=Path, help="the frame (PNG)")
    p.add_argument("--lens-seed", type=int, default=0, help="seed of the true lens (default 0)")
    p.add_argument("--tangential-px", type=float, default=0.0, help="tangential distortion, px (default 0)")
    p.add_argument("--tilt", type=float, default=0.0, metavar="DEG", help="camera tilt (default 0)")
    p.add_argument("--azimuth", type=float, default=0.0, metavar="DEG", help="direction of the tilt's axis")
    p.add_argument("--turn", type=float, default=0.0, metavar="DEG", help="turn about the optical axis")
    p.add_argument("--height", type=float, default=0.0, metavar="MM", help="away from focus along the axis")
    p.add_argument(
        "--defocus",
        type=float,
        default=F4_DEFOCUS_PX_PER_MM,
        metavar="PX_PER_MM",
        help=f"blur growth away from focus (default {F4_DEFOCUS_PX_PER_MM}: an f/4 1X macro)",
    )
    p.add_argument("--preset", choices=sorted(PRESETS), default="nominal", help="noise preset")
    p.add_argument("--seed", type=int, default=0, help="seed of the frame's noise (default 0)")
    p.add_argument("--truth", type=Path, default=None, metavar="FILE", help="write the truth as JSON")
    p.set_defaults(func=_render_target)


def _fail(message: str) -> int:
    sys.stderr.write(f"station sim: {message}\n")
    return 1


def _render_target(args: argparse.Namespace) -> int:
    if args.out_png.suffix.lower() != ".png":
        return _fail(f"{args.out_png}: the frame is written as PNG; name it .png")
    try:
        lens = true_intrinsics(args.lens_seed, tangential_px=args.tangential_px)
        view = ViewSpec(args.tilt, args.azimuth, args.turn, args.height)
        pose = TargetPose.from_view(view)
        image, truth = render_target(
            pose,
            intrinsics=lens,
            preset=get_preset(args.preset),
            defocus_px_per_mm=args.defocus,
            rng=np.random.default_rng(args.seed),
        )
        if not cv2.imwrite(str(args.out_png), image):
            return _fail(f"could not write {args.out_png} (does its folder exist?)")
        if args.truth is not None:
            doc = {
                "camera_model": lens.to_dict(),
                "target": STANDARD_TARGET.model_dump(),
                "view": {"tilt_deg": args.tilt, "azimuth_deg": args.azimuth, "turn_deg": args.turn},
                "height_mm": args.height,
                "defocus_px_per_mm": args.defocus,
                "pose": {"rotation": pose.rotation.tolist(), "translation_mm": pose.translation_mm.tolist()},
                "corners_px": [
                    None if not ok else xy
                    for xy, ok in zip(truth.corners_px.tolist(), truth.in_frame, strict=True)
                ],
            }
            args.truth.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    except (ValueError, OSError, cv2.error) as exc:
        return _fail(str(exc))
    sys.stderr.write(
        f"station sim: target through lens {args.lens_seed} (fx {lens.fx:.1f} px), "
        f"{int(truth.in_frame.sum())} corners in the frame -> {args.out_png}\n"
    )
    sys.stdout.write(f"{args.out_png}\n")
    return 0
