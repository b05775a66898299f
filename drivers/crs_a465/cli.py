"""``station robot``: talk to a C500C controller (a real one, ``station sim controller``, any emulator).

    station robot (--sim | --port PORT [--baud N]) [--json] COMMAND

COMMAND: ``status``, ``where``, ``home``, ``ready``, ``speed PERCENT``, ``joint AXIS DEGREES``
(relative), ``move-joints D1 D2 D3 D4 D5 D6`` (absolute). ``--sim`` starts a fresh controller twin
for this call (through the device registry: drivers never import ``sim``). Motion commands print the
position afterwards. Exit 0 on success, 1 when the controller or the host's checks refuse (the
message on stderr), 2 on a usage error.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Callable
from typing import Any, Protocol

from drivers.crs_a465 import open_robot
from drivers.crs_a465._robot import CrsA465
from station import config
from station.devices import JOINT_COUNT, DeviceError, RobotPosition, RobotStatus

log = logging.getLogger(__name__)


class _Twin(Protocol):
    """What this command needs of a controller twin built through the registry."""

    @property
    def port(self) -> str: ...

    def close(self) -> None: ...


def _out(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _err(text: str) -> None:
    sys.stderr.write(f"station robot: {text}\n")


def _fmt_row(values: tuple[float, ...] | None, unit: str) -> str:
    if values is None:
        return "unknown"
    return "  ".join(f"{v:+9.3f}" for v in values) + f"  ({unit})"


def _position_json(p: RobotPosition) -> dict[str, Any]:
    return {
        "joints_deg": list(p.joints_deg),
        "commanded_joints_deg": list(p.commanded_joints_deg),
        "world_mm_deg": None if p.world_mm_deg is None else list(p.world_mm_deg),
    }


def _print_position(p: RobotPosition, as_json: bool) -> None:
    if as_json:
        _out(json.dumps(_position_json(p)))
        return
    _out(f"joints     {_fmt_row(p.joints_deg, 'deg')}")
    _out(f"commanded  {_fmt_row(p.commanded_joints_deg, 'deg')}")
    _out(f"world      {_fmt_row(p.world_mm_deg, 'x y z mm, z/y/x rot deg')}")


def _print_status(s: RobotStatus, as_json: bool) -> None:
    fields = {
        "power": s.power,
        "homed": s.homed,
        "moving": s.moving,
        "speed_pct": s.speed_pct,
        "last_error": s.last_error,
    }
    if as_json:
        _out(json.dumps(fields))
        return
    for name, value in fields.items():
        if value is None:
            shown = "none" if name == "last_error" else "unknown"
        elif isinstance(value, bool):
            shown = "yes" if value else "no"
        else:
            shown = str(value)
        _out(f"{name:<11}{shown}")


def _run_command(robot: CrsA465, args: argparse.Namespace) -> None:
    name: str = args.robot_command
    if name == "status":
        _print_status(robot.status(), args.json)
        return
    if name == "where":
        _print_position(robot.where(), args.json)
        return
    actions: dict[str, Callable[[], None]] = {
        "home": robot.home,
        "ready": robot.ready,
        "speed": lambda: robot.set_speed(args.percent),
        "joint": lambda: robot.move_joint(args.axis, args.degrees),
        "move-joints": lambda: robot.move_joints(args.degrees),
    }
    actions[name]()
    if name == "speed":
        _print_status(robot.status(), args.json)
    else:
        robot.wait_settled()
        _print_position(robot.where(), args.json)


def handle(args: argparse.Namespace) -> int:
    """Run one ``station robot`` command; exit code 0 or 1."""
    twin: _Twin | None = None
    try:
        if args.sim:
            twin = config.build("controller", "sim", shell=args.shell, app_name=args.app_name)
            port = twin.port
        else:
            port = args.port
        safety: dict[str, Any] = {}
        if args.max_step is not None:
            safety["max_step_deg"] = args.max_step
        link: dict[str, Any] = {}
        if args.timeout is not None:
            link["reply_timeout_s"] = args.timeout
        robot = open_robot(
            port,
            shell=args.shell,
            app_name=args.app_name,
            baudrate=None if args.sim else args.baud,
            link=link,
            safety=safety,
        )
        with robot:
            _run_command(robot, args)
        return 0
    except DeviceError as exc:
        _err(str(exc))
        return 1
    except (config.ConfigurationError, ValueError) as exc:
        _err(str(exc))
        return 1
    finally:
        if twin is not None:
            twin.close()


def _percent(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"PERCENT must be a number, got {text!r}") from None


def _axis(text: str) -> int:
    try:
        axis = int(text)
    except ValueError:
        axis = 0
    if not 1 <= axis <= JOINT_COUNT:
        raise argparse.ArgumentTypeError(f"AXIS must be a joint number from 1 to {JOINT_COUNT}, got {text!r}")
    return axis


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg,unused-ignore]
    """Add ``station robot`` to the station's sub-commands."""
    parser = sub.add_parser(
        "robot",
        help="CRS A465 on a C500C controller: status, where, home, ready, speed, joint, move-joints",
        description="Talk to a C500C controller: a real one, `station sim controller`, or any emulator.",
    )
    target = parser.add_mutually_exclusive_group(required=True)
    target.add_argument("--sim", action="store_true", help="start a fresh controller twin for this call")
    target.add_argument("--port", help="serial port or pyserial URL of the controller (e.g. /dev/ttyS0)")
    parser.add_argument("--baud", type=int, default=57600, help="baud rate (default 57600)")
    parser.add_argument("--json", action="store_true", help="print JSON")
    parser.add_argument(
        "--shell",
        choices=("system", "application"),
        default="system",
        help="controller shell (default system)",
    )
    parser.add_argument("--app-name", default="ash", help="application shell name: its prompt is 'NAME> '")
    parser.add_argument(
        "--max-step", type=float, default=None, metavar="DEG", help="largest joint change per call"
    )
    parser.add_argument(
        "--timeout", type=float, default=None, metavar="S", help="reply timeout (default 3 s)"
    )
    commands = parser.add_subparsers(dest="robot_command", required=True, metavar="COMMAND")
    commands.add_parser("status", help="power, homing, speed (unknown where the controller cannot tell)")
    commands.add_parser("where", help="attained and commanded joints, and the WORLD row")
    commands.add_parser("home", help="home the arm")
    commands.add_parser("ready", help="go to the ready pose")
    speed = commands.add_parser("speed", help="set the speed override")
    speed.add_argument("percent", type=_percent, metavar="PERCENT")
    joint = commands.add_parser("joint", help="move one joint relatively")
    joint.add_argument("axis", type=_axis, metavar="AXIS")
    joint.add_argument("degrees", type=float, metavar="DEGREES")
    move = commands.add_parser("move-joints", help="move to six absolute joint angles")
    move.add_argument("degrees", type=float, nargs=JOINT_COUNT, metavar="D")
    parser.set_defaults(func=handle)


__all__ = ["handle", "register"]
