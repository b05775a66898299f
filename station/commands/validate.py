"""``station validate SET``: the seed's validation of a set taken on the X-Y table (section 4)."""

from __future__ import annotations

import argparse
import json
import sys

from station.batch import default_jobs
from station.commands._common import add_measure_options, params_from_args
from station.commands._parsing import SubParsers
from station.displacements import CALIBRATIONS, ValidationError, validate
from station.imagesets import ImageSetError, load_set
from station.text_tables import validation_report


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "validate",
        help="measure a validation set and compare with the table's displacements",
        description="Measure every image of SET (a folder with displacements.csv) and report the "
        "displacement errors after rigid (raw), similarity and affine (parallelogram) fits, in um.",
    )
    p.add_argument("set_dir", metavar="SET")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument(
        "--calibration",
        choices=CALIBRATIONS,
        default="series",
        help="series: one homography from all images (default); image: each image's own (the seed's)",
    )
    add_measure_options(p)
    p.set_defaults(func=lambda args: run(p, args))


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    params = params_from_args(parser, args)
    try:
        image_set = load_set(args.set_dir)
        jobs = args.jobs if args.jobs is not None else default_jobs()
        result = validate(image_set, params, jobs=jobs, calibration=args.calibration)
    except (ImageSetError, ValidationError) as exc:
        print(f"station validate: {exc}", file=sys.stderr)
        return 1
    if args.json:
        c = result.comparison
        doc = {
            "set": str(image_set.root),
            "mode": params.mode,
            "calibration": result.calibration,
            "images": len(result.results),
            "measured": int(result.used.sum()),
            **{f.kind: f.summary_um() for f in (c.rigid, c.similarity, c.affine)},
            "failures": [{"file": r.file, "error": r.error} for r in result.failures],
        }
        if result.center_error_px is not None and len(result.center_error_px):
            doc["center_error_px"] = {
                "mean": float(result.center_error_px.mean()),
                "max": float(result.center_error_px.max()),
            }
        print(json.dumps(doc))
    else:
        print(validation_report(result))
    return 0 if not result.failures else 1
