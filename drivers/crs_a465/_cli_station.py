"""``station robot``'s commands that need the station's configuration: ``jog`` and ``acknowledge``.

    station robot --config F jog joint J DELTA_DEG
    station robot --config F jog camera x|y|z|turn DELTA      (mm, or deg for turn)
    station robot --config F acknowledge
    station robot --config F selftest [--checks directions,world,ready,halt]

``selftest`` runs the controller self-test (``station.selftest``) over this robot and the configuration's
camera (``--sim``: a fresh simulated station in real time, its own cell and camera) and prints its
result (``--json``: one object); exit 0 when every check passed, 1 otherwise. Its halt check leaves the
stop latched: acknowledge it at the station afterwards.

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
from station import config
from station.jog import CAMERA_AXES, jog
from station.kinematics import Kinematics
from station.local_ack import LocalAcknowledgement
from station.selftest import CHECK_NAMES, SelftestResult, selftest_rig
from station.selftest import run_selftest as run_selftest_rig

__all__ = ["acknowledge", "add_parsers", "open_sim_station", "run_jog", "run_selftest"]


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
    selftest = commands.add_parser(
        "selftest",
        help="the controller self-test: joint directions against the camera, WORLD against the arm model,"
        " the ready pose, the halt key (needs --config, or --sim)",
        description="Check what the station assumes of the controller: each joint's direction against the"
        " camera's view of a crossing (start over an artifact's crossing, in focus: to-reference), WORLD"
        " against the station's arm model at 5 poses, the ready pose, and the halt key on a slow joint-6"
        " move (last: it leaves the stop latched for `acknowledge`). Every move checked, at the jog speed.",
    )
    selftest.add_argument(
        "--checks",
        default=",".join(CHECK_NAMES),
        metavar="LIST",
        help=f"comma-separated checks to run (default {','.join(CHECK_NAMES)})",
    )
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
        nominal = Kinematics(tool=station.camera_frame("jogging the camera").matrix())
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


class _OwnedStation:
    """A simulated station, closed like a twin (its devices' owners) after the robot."""

    def __init__(self, devices: config.StationDevices) -> None:
        self._devices = devices

    @property
    def port(self) -> str:
        return ""

    def close(self) -> None:
        self._devices.close_owned()


def open_sim_station(args: argparse.Namespace) -> tuple[CrsA465, _OwnedStation]:
    """``selftest --sim``: a whole simulated station in real time (the halt is timed), its own cell and
    camera (``args.station``, ``args.camera``); returns its robot and what closes the rest."""
    devices = config.open_sim_station(time_scale=1.0)
    robot = devices.robot
    if not isinstance(robot, CrsA465):
        devices.close_owned()
        raise TypeError(f"the simulated station's robot is a {type(robot).__name__}, not a CrsA465")
    args.station, args.camera = devices.config, devices.camera
    return robot, _OwnedStation(devices)


def run_selftest(robot: CrsA465, args: argparse.Namespace, out: TextIO | None = None) -> SelftestResult:
    """Run the self-test over ``robot`` (connected) and ``args.camera`` (or the configuration's camera,
    opened and closed here); print its result. ``args.exit_code``: 0 when it passed, else 1."""
    station = args.station
    checks = tuple(c.strip() for c in args.checks.split(",") if c.strip())
    camera = getattr(args, "camera", None)
    owned = camera is None
    if camera is None:
        camera = config.build("camera", station.camera.driver, **station.camera.options)
    try:
        camera.connect()
        limits = robot.guard.limits
        rig = selftest_rig(
            station,
            robot,
            camera,
            ready_pose_deg=limits.ready_pose_deg,
            max_step_deg=limits.max_step_deg,
        )
        result = run_selftest_rig(rig, checks=checks)
    finally:
        if owned:
            camera.close()
    out = sys.stdout if out is None else out
    if args.json:
        out.write(json.dumps(result.to_dict()) + "\n")
    else:
        out.write(f"selftest   {'passed' if result.passed else 'FAILED'}\n")
        for check in result.checks:
            out.write(f"{check.name:<11}{check.state:<13}{check.summary}\n")
        who = result.identity
        model, port = who.get("model") or "unknown model", who.get("port") or "unknown port"
        out.write(f"identity   {model} on {port}\n")
        if result.latched:
            out.write(
                "the stop is latched (the halt check): look at the arm, then acknowledge it at the station's"
                " terminal: station robot --config FILE acknowledge\n"
            )
    out.flush()
    args.exit_code = 0 if result.passed else 1
    return result


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
