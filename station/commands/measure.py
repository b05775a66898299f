"""``station measure``: measure image files; one JSON object per image per line with ``--json``."""

from __future__ import annotations

import argparse
import json
import sys

from tqdm import tqdm

from station import scale_calibration
from station.batch import FileResult, default_jobs, measure_files
from station.commands import SubParsers
from station.commands._common import SMALL_FILE_MAX_BYTES, add_measure_options, finite_float, params_from_args
from station.imageio import (
    DEFAULT_MAX_BYTES,
    DEFAULT_MAX_DECODED_BYTES,
    DEFAULT_MAX_PIXELS,
    ImageFileError,
    ImageLimits,
    read_file_bytes,
)
from station.report import measurement_rows


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "measure",
        help="measure the crossing in image files",
        description="Measure the artifact's crossing in each IMAGE. Exit 0 when all were measured, "
        "1 when any failed, 2 for usage errors.",
    )
    p.add_argument("images", nargs="+", metavar="IMAGE")
    p.add_argument("--json", action="store_true", help="one JSON object per image per line (stdout)")
    p.add_argument(
        "--camera-model",
        metavar="FILE",
        default=None,
        help="correct lens distortion (precise mode): OpenCV camera matrix and distortion coefficients "
        "(JSON, or the YAML/XML cv2.FileStorage writes)",
    )
    p.add_argument(
        "--scale-calibration",
        metavar="FILE",
        default=None,
        help="measure with the groove width a validation session estimated (JSON {groove_width_mm, u_mm, "
        "session_id}, as in DATA/scale-calibration.json); recorded as diagnostics.scale_calibration",
    )
    p.add_argument(
        "--max-file-mb",
        type=finite_float("--max-file-mb", positive=True),
        default=DEFAULT_MAX_BYTES / 2**20,
        metavar="MB",
        help=f"refuse image files larger than this (MiB; default {DEFAULT_MAX_BYTES // 2**20})",
    )
    p.add_argument(
        "--max-megapixels",
        type=finite_float("--max-megapixels", positive=True),
        default=DEFAULT_MAX_PIXELS / 1e6,
        metavar="MPX",
        help=f"refuse images whose header declares more pixels (default {DEFAULT_MAX_PIXELS / 1e6:g} Mpx)",
    )
    p.add_argument(
        "--max-decoded-mb",
        type=finite_float("--max-decoded-mb", positive=True),
        default=DEFAULT_MAX_DECODED_BYTES / 2**20,
        metavar="MB",
        help="refuse images whose header declares a larger decoded size, width x height x channels x bytes "
        f"per sample (MiB; default {DEFAULT_MAX_DECODED_BYTES // 2**20})",
    )
    add_measure_options(p)
    p.set_defaults(func=lambda args: run(p, args))


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    params = params_from_args(parser, args)
    calibration: dict[str, object] | None = None
    if args.scale_calibration is not None:
        try:  # a regular file of sensible size first: a FIFO or /dev/zero would hang the read
            read_file_bytes(
                args.scale_calibration, max_bytes=SMALL_FILE_MAX_BYTES, what="scale calibration file"
            )
            cal = scale_calibration.load(args.scale_calibration)
        except ImageFileError as exc:
            parser.error(f"--scale-calibration {exc}")
        except scale_calibration.ScaleCalibrationError as exc:
            parser.error(str(exc))
        if not any(a.split("=", 1)[0].strip().lower() == "groove_width_mm" for a in args.assignments):
            params = params.with_values(groove_width_mm=cal.groove_width_mm)
        calibration = cal.record(args.scale_calibration)
    limits = ImageLimits(
        max_bytes=max(1, int(args.max_file_mb * 2**20)),
        max_pixels=max(1, int(args.max_megapixels * 1e6)),
        max_decoded_bytes=max(1, int(args.max_decoded_mb * 2**20)),
    )
    jobs = args.jobs if args.jobs is not None else default_jobs()
    results: list[FileResult] = []
    # progress on stderr, shown only on a terminal (tqdm's disable=None)
    bar = tqdm(total=len(args.images), unit="img", file=sys.stderr, disable=None, leave=False)
    for result in measure_files(args.images, params, jobs=jobs, limits=limits):
        bar.update()
        results.append(result)
        if not result.ok:
            print(f"station measure: {result.file}: {result.error}", file=sys.stderr)
        if args.json:
            doc = result.to_json()
            if calibration is not None and doc.get("ok"):
                doc["diagnostics"]["scale_calibration"] = calibration
            print(json.dumps(doc), flush=True)
    bar.close()
    if not args.json:
        print(measurement_rows(results))
    return 0 if all(r.ok for r in results) else 1
