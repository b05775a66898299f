"""``station sweep SET``: the seed's Table 1 (or any grid) over a validation set."""

from __future__ import annotations

import argparse
import json
import sys

from pydantic import ValidationError as PydanticValidationError

from station.batch import default_jobs
from station.commands._common import add_measure_options, params_from_args
from station.commands._parsing import SubParsers
from station.displacements import CALIBRATIONS
from station.imagesets import ImageSetError, load_set
from station.parameter_study import PRECISE_GRID, Trial, best, grid, parse_grid, run_sweep, seed_trials
from station.text_tables import SweepRow, sweep_report


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "sweep",
        help="parameter study over a validation set (the seed's Table 1 by default)",
        description="Measure SET under a grid of parameters and print MaxE / MeanE (mm, after the "
        "well-fit parallelogram) per trial, marking the best. Paper mode's default grid is the seed's "
        "nine trials (TW = TESTWIDTH, TH = TESTHEIGHT); precise mode's is window_sigmas x outlier_sigma.",
    )
    p.add_argument("set_dir", metavar="SET")
    p.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="NAME=V1,V2,...",
        help="sweep a parameter over values (repeat for a Cartesian product), e.g. --grid SKIP=1,10,20",
    )
    p.add_argument(
        "--calibration",
        choices=CALIBRATIONS,
        default="image",
        help="image: each image's own homography, as the seed (default); series: one for the set",
    )
    p.add_argument("--json", action="store_true", help="print the trials as JSON")
    add_measure_options(p)
    p.set_defaults(func=lambda args: run(p, args))


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    if args.mode is None:
        args.mode = "paper"
    base = params_from_args(parser, args)
    try:
        values = parse_grid(args.grid)
    except ValueError as exc:
        parser.error(str(exc))
    if values:
        overrides = grid(values)
    elif base.mode == "paper":
        overrides = seed_trials()
    else:
        overrides = grid(PRECISE_GRID)
    try:
        for change in overrides:
            base.with_values(**change)
    except PydanticValidationError as exc:
        parser.error(f"invalid grid value: {exc.errors(include_url=False)[0]['msg']}")
    try:
        image_set = load_set(args.set_dir)
    except ImageSetError as exc:
        print(f"station sweep: {exc}", file=sys.stderr)
        return 1
    jobs = args.jobs if args.jobs is not None else default_jobs()

    def progress(t: Trial) -> None:
        state = f"MeanE {t.mean_e_mm:.5f} mm" if t.result else f"failed: {t.error}"
        print(f"station sweep: trial {t.number}/{len(overrides)} {t.overrides}: {state}", file=sys.stderr)

    trials = run_sweep(image_set, base, overrides, jobs=jobs, calibration=args.calibration, on_trial=progress)
    winner = best(trials)
    if args.json:
        print(json.dumps(_as_json(trials, winner, base.mode)))
    else:
        print(_as_table(trials, winner, base.mode, seed_layout=not values and base.mode == "paper"))
    return 0 if winner is not None else 1


def _as_json(trials: list[Trial], winner: Trial | None, mode: str) -> dict[str, object]:
    return {
        "mode": mode,
        "best": winner.number if winner else None,
        "trials": [
            {
                "trial": t.number,
                "params": t.overrides,
                "max_e_mm": t.max_e_mm if t.result else None,
                "mean_e_mm": t.mean_e_mm if t.result else None,
                "raw_max_um": t.result.comparison.rigid.max if t.result else None,
                "raw_mean_um": t.result.comparison.rigid.mean if t.result else None,
                "error": t.error,
            }
            for t in trials
        ],
    }


def _as_table(trials: list[Trial], winner: Trial | None, mode: str, *, seed_layout: bool) -> str:
    rows = [
        SweepRow(
            t.number,
            t.overrides,
            t.max_e_mm if t.result else None,
            t.mean_e_mm if t.result else None,
            t.error,
        )
        for t in trials
    ]
    return sweep_report(rows, winner.number if winner else None, mode, seed_layout=seed_layout)
