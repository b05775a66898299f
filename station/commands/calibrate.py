"""``station calibrate SESSION``: identify the arm's kinematic errors again from a stored calibration session.

Capture and optimisation are separate (the raw images, their measurements, the joints and the distance
readings stay in the record), so the identification re-runs on any stored ``calibration`` session, e.g.
with another hold-out draw (``--param seed=3``) or after a software update. It reads the session's
captures, its configuration snapshot (the cell: artifacts, optics, the sensor's mount) and its plan
parameters, and prints the same results object as ``station run calibration``; ``--json`` prints
``{"id", "kind", "state", "results", "error"}``: ``station run --json``'s model. ``--out FILE`` writes
the calibrated parameter set (versioned JSON) that ``station.calibration.load_kinematics(FILE)`` and
``station robot ... move-camera ... --calibration FILE`` load. Nothing is moved, nothing in the record
is changed.
Exit 0 on success, 1 when the identification fails, 2 for usage errors (unknown session, wrong kind).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from station.commands._parsing import SubParsers, add_record_options
from station.commands.run import parse_params
from station.kinds import summary
from station.plans import PlanError


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "calibrate",
        help="identify the arm's kinematic errors from a stored calibration session",
        description="Identify the arm's kinematic errors again from a stored calibration session (no"
        " motion); print the results and optionally write the calibrated parameter set.",
    )
    p.add_argument("session", metavar="SESSION", help="a calibration session's id (or a unique prefix)")
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a parameter of the analysis (holdout_fraction, seed, loss, f_scale)",
    )
    p.add_argument("--out", metavar="FILE", help="write the calibrated parameter set (JSON) here")
    p.add_argument("--json", action="store_true", help="print the outcome as one JSON object (last line)")
    add_record_options(p)
    p.set_defaults(func=lambda args: run_calibrate(p, args))


ANALYSIS_PARAMS = ("holdout_fraction", "seed", "loss", "f_scale")


def run_calibrate(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    from station.calibration import CalibrationResult
    from station.kinds.calibration.analysis import analyse_calibration
    from station.kinds.calibration.params import calibration_cell_from_config
    from station.kinds.calibration.plan import CALIBRATION
    from station.plans import parse_params as validate_params
    from station.record import RecordError
    from station.resources import SessionOutcome, dumps
    from station.runner import SessionState, stored_captures
    from station.session import open_record
    from station.vision import MeasureParams

    overrides = parse_params(parser, args.param)
    unknown = sorted(set(overrides) - set(ANALYSIS_PARAMS))
    if unknown:
        print(
            f"station calibrate: only the analysis's parameters can change ({', '.join(ANALYSIS_PARAMS)});"
            f" not {', '.join(unknown)}: the captures were planned with the others",
            file=sys.stderr,
        )
        return 2
    try:
        record = open_record(args.data, args.database)
    except RecordError as exc:
        print(f"station calibrate: {exc}", file=sys.stderr)
        return 2
    with record:
        try:
            session = record.get_session(args.session)
        except RecordError as exc:
            print(f"station calibrate: {exc}", file=sys.stderr)
            return 2
        if session.kind != CALIBRATION.name:
            print(
                f"station calibrate: session {session.id} is a {session.kind} session, not a calibration",
                file=sys.stderr,
            )
            return 2
        try:
            params: Any = validate_params(CALIBRATION, {**session.params.get("plan", {}), **overrides})
        except PlanError as exc:  # a bad value given on the command line: a usage error
            print(f"station calibrate: {exc}", file=sys.stderr)
            return 2
        try:
            measure = MeasureParams.model_validate(session.params.get("measure") or {})
            cell = calibration_cell_from_config(session.config, measure)
            if cell is None:
                raise PlanError(
                    f"session {session.id}'s configuration snapshot has no [calibration] section, robot or"
                    " distance sensor: it cannot be identified"
                )
            planned = len(CALIBRATION.configurations(params, cell))
            results = analyse_calibration(params, cell, stored_captures(record, session.id), planned=planned)
        except PlanError as exc:
            print(f"station calibrate: {exc}", file=sys.stderr)
            return 1
    if args.out:
        path = CalibrationResult.model_validate(results["calibration"]).save(Path(args.out))
        print(f"calibration: {path}", file=sys.stderr if args.json else sys.stdout)
    if args.json:
        outcome = SessionOutcome.model_construct(
            id=session.id, kind=session.kind, state=SessionState(session.state), results=results, error=None
        )
        print(dumps(outcome))
    else:
        print(f"session {session.id} ({session.kind}), identified again:")
        print(summary(session.kind, results))
    return 0
