"""``station robot``'s commands that need the station's configuration: ``jog`` and ``acknowledge``.

    station robot --config F jog joint J DELTA_DEG
    station robot --config F jog camera x|y|z|turn DELTA      (mm, or deg for turn)
    station robot --config F acknowledge

A jog runs at the configuration's ``jog_speed_pct`` (default 10 %, never above ``max_speed_pct``), every
jog checked (joint limits, keep-out along the path, the speed cap) before it is sent
(``station.jog``); a camera jog goes through the nominal model with the configuration's camera mounting,
so it works before any calibration. ``acknowledge`` releases the robot's stop latch after a stop, an
E-stop or a controller error: it must be typed at the station's own terminal (not over SSH, not from a
script), by a person who has looked at the arm, and answered ``yes``.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any, TextIO

from drivers.crs_a465._robot import CrsA465
from station.jog import CAMERA_AXES, jog
from station.kinematics import Kinematics
from station.local_ack import LocalAcknowledgement

__all__ = ["acknowledge", "add_parsers", "run_jog"]


def add_parsers(commands: Any) -> None:
    """Add ``jog`` and ``acknowledge`` to ``station robot``'s sub-commands."""
    jog_parser = commands.add_parser(
        "jog",
        help="a small move of one joint or of the camera in its own frame, at the jog speed (needs --config"
        " for the camera)",
        description="Jog one joint (deg) or the camera along its own x, y (the image's right, down), z (the"
        " optical axis, + toward what it looks at) in mm, or turn it about the optical axis (deg), through"
        " the nominal model with the configuration's camera mounting; every jog checked (limits, keep-out"
        " along the path, speed cap) before it is sent.",
    )
    what = jog_parser.add_subparsers(dest="jog_kind", required=True, metavar="joint|camera")
    joint = what.add_parser("joint", help="jog joint J by DELTA_DEG")
    joint.add_argument("jog_joint", type=int, metavar="J", help="joint 1-6")
    joint.add_argument("jog_delta", type=float, metavar="DELTA_DEG")
    camera = what.add_parser("camera", help="jog the camera along x, y, z (mm) or turn it (deg)")
    camera.add_argument("jog_axis", choices=CAMERA_AXES, metavar="x|y|z|turn")
    camera.add_argument("jog_delta", type=float, metavar="DELTA")
    commands.add_parser(
        "acknowledge",
        help="release the stop latch after a stop, E-stop or controller error (at the station's terminal)",
        description="Release the robot's stop latch: typed at the station's own terminal by a person who has"
        " looked at the arm and the cell (not over SSH, not from a script), answering yes.",
    )


def run_jog(robot: CrsA465, args: argparse.Namespace, out: TextIO | None = None) -> None:
    """Jog as asked, at the robot's ``jog_speed_pct``; print what was done (``--json``: one object)."""
    nominal = None
    if args.jog_kind == "camera":
        station = getattr(args, "station", None)
        if station is None:
            raise ValueError(
                "jog camera needs --config FILE: the camera's mounting on the flange ([camera] mount)"
            )
        nominal = Kinematics(tool=station.camera_mount().matrix())
    done = jog(
        robot,
        joint=args.jog_joint if args.jog_kind == "joint" else None,
        camera_axis=args.jog_axis if args.jog_kind == "camera" else None,
        delta=args.jog_delta,
        nominal=nominal,
        speed_pct=robot.guard.limits.jog_speed_pct,
    )
    doc = done.to_dict()
    out = sys.stdout if out is None else out
    if args.json:
        out.write(json.dumps(doc) + "\n")
    else:
        unit = doc["unit"]
        what = f"joint {done.axis}" if done.kind == "joint" else f"camera {done.axis}"
        out.write(f"jogged {what} by {done.delta:+g} {unit} at {done.speed_pct:g} %\n")
        out.write("joints     " + "  ".join(f"{v:+9.3f}" for v in done.final.joints_deg) + "  (deg)\n")
    out.flush()


def acknowledge(
    robot: CrsA465,
    *,
    stdin: TextIO | None = None,
    out: TextIO | None = None,
    environ: dict[str, str] | None = None,
) -> str | None:
    """At the station's terminal: say what latched the stop, ask for ``yes``, and release the latch.

    Returns what had latched it (``None``: nothing was latched). Raises RemoteAcknowledgementError when
    standard input is not the station's own terminal, and ValueError when the answer is not ``yes``.
    """
    stream = sys.stdin if stdin is None else stdin
    out = sys.stderr if out is None else out
    reason = robot.latch_reason
    if reason is None:
        out.write("station robot: no stop is latched; nothing to acknowledge\n")
        return None
    ack_check = LocalAcknowledgement.from_terminal(stream, environ=environ)  # refuses before it asks
    out.write(
        f"station robot: the stop is latched: {reason}\n"
        "Look at the arm and the cell. Is everything clear for the arm to move again? Type yes: "
    )
    out.flush()
    answer = stream.readline().strip().lower()
    if answer != "yes":
        raise ValueError(f"not acknowledged (answered {answer!r}): the stop stays latched")
    ack = LocalAcknowledgement.from_terminal(stream, environ=environ) if not ack_check.fresh() else ack_check
    return robot.acknowledge_stop(ack)
