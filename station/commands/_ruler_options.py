"""``station measure --artifact ruler``: its options, their checks (exit 2 on misuse) and its table."""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence

from pydantic import ValidationError

from station._pydantic import problems
from station.batch import FileResult
from station.camera_model import CameraModelError
from station.commands._common import SMALL_FILE_MAX_BYTES, load_camera_model_file
from station.imageio import ImageFileError, read_file_bytes
from station.text_tables import table
from station.vision import RulerParams, RulerSpec, parse_ruler_assignments

ARTIFACTS = ("cross", "ruler")


def add_artifact_options(parser: argparse.ArgumentParser) -> None:
    """``--artifact`` and ``--ruler``."""
    parser.add_argument(
        "--artifact",
        choices=ARTIFACTS,
        default="cross",
        help="what the images show: the crossed-groove artifact (default) or the graduated ruler",
    )
    parser.add_argument(
        "--ruler",
        metavar="FILE",
        default=None,
        help="with --artifact ruler: the ruler's description (JSON: length_mm, pitch_mm, pitch_u_ppm, "
        "graduation_u_nm, code, ...; station/vision/RULER.md); default the design's 250 mm ruler",
    )


def load_ruler(path: str) -> RulerSpec:
    """A ruler description file, checked like any other input; ValueError saying what is wrong."""
    try:
        data = read_file_bytes(path, max_bytes=SMALL_FILE_MAX_BYTES, what="ruler description file")
    except ImageFileError as exc:
        raise ValueError(f"--ruler {exc}") from None
    try:
        doc = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"--ruler {path}: not a JSON ruler description ({exc})") from None
    try:
        return RulerSpec.model_validate(doc)
    except ValidationError as exc:
        raise ValueError(f"--ruler {path}: {problems(exc)}") from None


def ruler_params_from_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> RulerParams:
    """The ruler measurement's parameters; a cross-only option or a bad value is a usage error."""
    if args.mode is not None:
        parser.error("--mode applies to the cross only (the ruler has one method)")
    if args.scale_calibration is not None:
        parser.error(
            "--scale-calibration applies to the cross only: the ruler's scale is its calibrated pitch "
            "(--ruler FILE describes it)"
        )
    try:
        values: dict[str, object] = dict(parse_ruler_assignments(args.assignments))
        if args.ruler is not None:
            values["ruler"] = load_ruler(args.ruler)
        if args.camera_model:
            values["camera_matrix"], values["dist_coeffs"] = load_camera_model_file(args.camera_model)
        return RulerParams.model_validate(values)
    except ValidationError as exc:
        parser.error(f"invalid ruler parameter: {problems(exc)}")
    except (ValueError, CameraModelError) as exc:
        parser.error(str(exc))


def ruler_rows(results: Sequence[FileResult]) -> str:
    """The text table of ``station measure --artifact ruler`` without ``--json``."""
    rows = []
    for r in results:
        m = r.ruler
        if m is None:
            rows.append([r.file, "FAILED", "", "", r.error or ""])
        else:
            rows.append(
                [r.file, f"{m.position_mm:12.6f}", f"{m.offset_mm:+9.5f}", f"{m.angle_deg:+9.4f}", ""]
            )
    return table(["file", "position_mm", "offset_mm", "angle_deg", "error"], rows)
