"""Options shared by the measuring sub-commands."""

from __future__ import annotations

import argparse

from pydantic import ValidationError

from station.batch import default_jobs
from station.camera_model import load_camera_model
from station.vision import MeasureParams, parse_assignments


def add_measure_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--mode",
        choices=["precise", "paper"],
        default=None,
        help="algorithm: precise (default) or paper (the seed's, Table 1 trial 7 defaults)",
    )
    parser.add_argument(
        "--set",
        dest="assignments",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set a parameter (case-insensitive names, e.g. --set TESTWIDTH=5 --set filter=gauss)",
    )
    parser.add_argument(
        "-j",
        "--jobs",
        type=int,
        default=None,
        help=f"worker processes (default: all cores, {default_jobs()})",
    )


def params_from_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> MeasureParams:
    """Build the parameter model; a bad --set is a usage error (exit 2) naming the parameter."""
    try:
        values: dict[str, object] = dict(parse_assignments(args.assignments))
        if args.mode is not None:
            values["mode"] = args.mode
        if getattr(args, "camera_model", None):
            values["camera_matrix"], values["dist_coeffs"] = load_camera_model(args.camera_model)
        return MeasureParams.model_validate(values)
    except ValueError as exc:
        if isinstance(exc, ValidationError):
            detail = "; ".join(
                f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in exc.errors(include_url=False)
            )
            parser.error(f"invalid parameter: {detail}")
        parser.error(str(exc))
