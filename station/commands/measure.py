"""``station measure``: measure image files; one JSON object per image per line with ``--json``."""

from __future__ import annotations

import argparse
import json
import sys

from tqdm import tqdm

from station.batch import FileResult, default_jobs, measure_files
from station.commands import SubParsers
from station.commands._common import add_measure_options, params_from_args
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
    add_measure_options(p)
    p.set_defaults(func=lambda args: run(p, args))


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    params = params_from_args(parser, args)
    jobs = args.jobs if args.jobs is not None else default_jobs()
    results: list[FileResult] = []
    # progress on stderr, shown only on a terminal (tqdm's disable=None)
    bar = tqdm(total=len(args.images), unit="img", file=sys.stderr, disable=None, leave=False)
    for result in measure_files(args.images, params, jobs=jobs):
        bar.update()
        results.append(result)
        if not result.ok:
            print(f"station measure: {result.file}: {result.error}", file=sys.stderr)
        if args.json:
            print(json.dumps(result.to_json()), flush=True)
    bar.close()
    if not args.json:
        print(measurement_rows(results))
    return 0 if all(r.ok for r in results) else 1
