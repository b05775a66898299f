"""``station measure``: measure image files; one JSON object per image per line with ``--json``."""

from __future__ import annotations

import argparse
import json
import sys

from tqdm import tqdm

from station import scale_calibration
from station.batch import FileResult, default_jobs
from station.commands._common import (
    SMALL_FILE_MAX_BYTES,
    add_compute_options,
    add_measure_options,
    compute_spec,
    finite_float,
    params_from_args,
)
from station.commands._parsing import SubParsers
from station.commands._ruler_options import add_artifact_options, ruler_params_from_args, ruler_rows
from station.compute import ComputeError, ComputeSpec, open_backend
from station.imageio import (
    DEFAULT_MAX_BYTES,
    DEFAULT_MAX_DECODED_BYTES,
    DEFAULT_MAX_PIXELS,
    ImageFileError,
    ImageLimits,
    read_file_bytes,
)
from station.text_tables import measurement_rows
from station.vision import MeasureParams, RulerParams, parse_assignments


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "measure",
        help="measure the crossing (or the ruler) in image files",
        description="Measure the artifact's crossing (or, with --artifact ruler, the position along the "
        "ruler) in each IMAGE. Exit 0 when all were measured, 1 when any failed (or the cluster failed), "
        "2 for usage errors.",
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
    add_compute_options(p)
    add_artifact_options(p)
    p.set_defaults(func=lambda args: run(p, args))


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    spec = compute_spec(parser, args, jobs=default_jobs()) or ComputeSpec(jobs=args.jobs or default_jobs())
    if args.artifact == "ruler":
        return _measure(parser, args, ruler_params_from_args(parser, args), None, spec)
    if args.ruler is not None:
        parser.error("--ruler applies to --artifact ruler only")
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
        given = parse_assignments(args.assignments)  # checked by params_from_args
        params = params.with_values(**scale_calibration.width_unless_set(cal, given))
        calibration = cal.record(args.scale_calibration)
    return _measure(parser, args, params, calibration, spec)


def _measure(
    parser: argparse.ArgumentParser,
    args: argparse.Namespace,
    params: MeasureParams | RulerParams,
    calibration: dict[str, object] | None,
    spec: ComputeSpec,
) -> int:
    limits = ImageLimits(
        max_bytes=max(1, int(args.max_file_mb * 2**20)),
        max_pixels=max(1, int(args.max_megapixels * 1e6)),
        max_decoded_bytes=max(1, int(args.max_decoded_mb * 2**20)),
    )
    results: list[FileResult] = []
    # progress on stderr, shown only on a terminal (tqdm's disable=None)
    bar = tqdm(total=len(args.images), unit="img", file=sys.stderr, disable=None, leave=False)
    backend = open_backend(spec)
    try:
        for result in backend.measure(args.images, params, limits=limits):
            bar.update()
            results.append(result)
            if not result.ok:
                print(f"station measure: {result.file}: {result.error}", file=sys.stderr)
            if args.json:
                doc = result.to_json()
                if calibration is not None and doc.get("ok"):
                    doc["diagnostics"]["scale_calibration"] = calibration
                print(json.dumps(doc), flush=True)
    except ComputeError as exc:
        bar.close()
        print(
            f"station measure: {exc} ({len(results)} of {len(args.images)} images measured)", file=sys.stderr
        )
        return 1
    finally:
        backend.close()
    bar.close()
    if not args.json:
        print(ruler_rows(results) if isinstance(params, RulerParams) else measurement_rows(results))
    return 0 if all(r.ok for r in results) else 1
