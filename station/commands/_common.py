"""Options shared by the measuring sub-commands, and the checks of their values (exit 2 on misuse)."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

from pydantic import ValidationError

from station.batch import default_jobs, max_jobs
from station.camera_model import CameraModelError, load_camera_model
from station.compute import CLUSTER_HELP, ComputeSpec, parse_cluster
from station.imageio import ImageFileError, read_file_bytes
from station.vision import MeasureParams, parse_assignments
from station.vision._params import allowed_range

#: A camera model or scale calibration file is a few hundred bytes; anything far larger is not one.
SMALL_FILE_MAX_BYTES = 1024 * 1024


def bounded_int(name: str, low: int, high: int) -> Callable[[str], int]:
    """An argparse ``type`` accepting integers from ``low`` to ``high``, naming the option otherwise."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{name} must be a whole number from {low} to {high}, got {text!r}"
            ) from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{name} must be from {low} to {high}, got {value}")
        return value

    return parse


def finite_float(name: str, *, positive: bool = False) -> Callable[[str], float]:
    """An argparse ``type`` accepting finite numbers (``positive``: above 0), naming the value otherwise."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{name} must be a finite number, got {text!r}")
        if positive and value <= 0:
            raise argparse.ArgumentTypeError(f"{name} must be above 0, got {text!r}")
        return value

    return parse


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
        type=bounded_int("--jobs", 1, max_jobs()),
        default=None,
        help=f"worker processes, 1 to {max_jobs()} (default: all cores, {default_jobs()})",
    )


def cluster_value(text: str) -> str:
    """An argparse ``type`` for ``--cluster``: ``local``, ``local:N`` or a scheduler's address."""
    try:
        return parse_cluster(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_compute_options(parser: argparse.ArgumentParser) -> None:
    """``--cluster`` and ``--ship-images``: where the frames are measured (``station.compute``)."""
    parser.add_argument("--cluster", type=cluster_value, default=None, metavar="ADDRESS", help=CLUSTER_HELP)
    parser.add_argument(
        "--ship-images",
        action="store_true",
        help="send each frame's bytes to the cluster's workers (for workers that do not share the data "
        "directory at the same path)",
    )


def compute_spec(
    parser: argparse.ArgumentParser, args: argparse.Namespace, *, jobs: int
) -> ComputeSpec | None:
    """The backend the command line names (None: not named, the default applies); ``jobs``: the local
    pool's size when ``--jobs`` is not given. Usage errors exit 2."""
    if args.cluster is None:
        if args.ship_images:
            parser.error("--ship-images sends the frames to a cluster's workers: give --cluster too")
        return None
    if args.cluster != "local" and args.jobs is not None:
        parser.error(
            "--jobs sizes the local pool; on a cluster its workers measure (size them with "
            "`dask worker --nworkers N`, or --cluster local:N here): drop --jobs or --cluster"
        )
    try:
        return ComputeSpec(args.cluster, args.jobs or jobs, args.ship_images)
    except ValueError as exc:
        parser.error(str(exc))


def _describe(exc: ValidationError) -> str:
    parts = []
    for e in exc.errors(include_url=False):
        loc = ".".join(str(p) for p in e["loc"])
        field = str(e["loc"][0]) if e["loc"] else ""
        where = f" (allowed: {allowed_range(field)})" if field in MeasureParams.model_fields else ""
        value = f" = {e['input']!r}" if loc and not isinstance(e["input"], dict) else ""
        parts.append(f"{loc}{value}: {e['msg']}{where}" if loc else str(e["msg"]))
    return "; ".join(parts)


def load_camera_model_file(path: str) -> tuple[list[list[float]], list[float]]:
    """A camera model file, checked like any other input: a regular file of sensible size."""
    try:
        read_file_bytes(path, max_bytes=SMALL_FILE_MAX_BYTES, what="camera model file")
    except ImageFileError as exc:
        raise CameraModelError(f"--camera-model {exc}") from None
    return load_camera_model(path)


def params_from_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> MeasureParams:
    """Build the parameter model; a bad --set is a usage error (exit 2) naming the value and range."""
    try:
        values: dict[str, object] = dict(parse_assignments(args.assignments))
        if args.mode is not None:
            values["mode"] = args.mode
        if getattr(args, "camera_model", None):
            values["camera_matrix"], values["dist_coeffs"] = load_camera_model_file(args.camera_model)
        return MeasureParams.model_validate(values)
    except ValueError as exc:
        if isinstance(exc, ValidationError):
            parser.error(f"invalid parameter: {_describe(exc)}")
        parser.error(str(exc))
