"""``station robot``: talk to a C500C controller (a real one, ``station sim controller``, any emulator).

    station robot (--sim | --port PORT [--baud N] | --config FILE) [--config FILE] [--json] COMMAND

COMMAND: ``status``, ``where``, ``home``, ``ready``, ``speed PERCENT``, ``joint AXIS DEGREES``
(relative), ``move-joints D1 D2 D3 D4 D5 D6`` (absolute), ``move-camera X Y Z Z_ROT Y_ROT X_ROT
--calibration FILE`` (a compensated move: the calibrated model's inverse kinematics, then joint
moves), ``to-reference`` (the arm's route from wherever it is to the station's reference pose,
``station.arm_route``: needs ``--config``), ``jog joint J DELTA`` / ``jog camera x|y|z|turn DELTA``
and ``acknowledge`` (``_cli_station``), ``selftest [--checks LIST]`` (``station.selftest``: exit 0 when
every check passed, 1 otherwise; with ``--sim`` a whole simulated station in real time). ``--config
FILE`` is the station configuration: its ``[robot]`` port (when neither ``--sim`` nor ``--port`` is given),
reference pose, safety limits (keep-out volumes, speed cap, carried bodies from the mounts) for every
command (``--max-step`` still overrides its step), the camera's mounting, and the data directory that
keeps the stop latch across calls. ``--sim`` starts a fresh controller twin
for this call (through the device registry: drivers never import ``sim``). Motion commands return once
the arm has arrived, then print the position. Exit 0 on success, 1 when the controller or the host's
checks refuse (the message on stderr), 2 on a usage error or a bad option value (one line, nothing
opened). SIGINT and SIGTERM stop the arm (best effort: the E-stop is the stop), print where it is and
exit 130 and 143.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import signal
import sys
import threading
from collections.abc import Callable
from types import FrameType
from typing import Any, Protocol

from pydantic import ValidationError

from drivers.crs_a465 import _cli_station, build_robot
from drivers.crs_a465._link import LinkSettings
from drivers.crs_a465._motion import MotionSettings
from drivers.crs_a465._robot import CrsA465
from drivers.crs_a465._safety import SafetyLimits
from station import config
from station.arm_route import go_to_reference
from station.devices import JOINT_COUNT, DeviceError, RobotPosition, RobotStatus
from station.local_ack import RemoteAcknowledgementError

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
        "calibrated": s.calibrated,
        "arm_type": s.arm_type,
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
    if name == "jog":
        _cli_station.run_jog(robot, args)
        return
    if name == "selftest":
        _cli_station.run_selftest(robot, args)
        return
    actions: dict[str, Callable[[], None]] = {
        "home": robot.home,
        "ready": robot.ready,
        "speed": lambda: robot.set_speed(args.percent),
        "joint": lambda: robot.move_joint(args.axis, args.degrees),
        "move-joints": lambda: robot.move_joints(args.degrees),
        "move-camera": lambda: _move_camera(robot, args),
        "to-reference": lambda: _to_reference(robot, args),
    }
    actions[name]()  # motions return once the arm has arrived
    if name == "to-reference":
        return
    if name == "speed":
        _print_status(robot.status(), args.json)
    else:
        _print_position(robot.where(), args.json)


def _move_camera(robot: CrsA465, args: argparse.Namespace) -> None:
    from station.camera_moves import move_camera
    from station.kinematics import pose_from_world_row

    pose = pose_from_world_row(args.pose)
    move_camera(robot, args.calibrated, pose, max_step_deg=robot.guard.limits.max_step_deg * 0.9)


def _to_reference(robot: CrsA465, args: argparse.Namespace) -> None:
    """The route to the configuration's reference pose, every move checked before the first is sent."""
    done = go_to_reference(robot, args.reference, max_step_deg=robot.guard.limits.max_step_deg)
    if args.json:
        _out(done.model_dump_json())
        return
    how = "through the lift pose" if done.via_lift else "direct"
    n = len(done.moves)
    _out(f"route      {how}, {n} move{'s' if n != 1 else ''}" if n else "route      none: already there")
    for k, q in enumerate(done.moves, start=1):
        _out(f"move {k:<6}{_fmt_row(tuple(q), 'deg')}")
    final = done.final_pose
    _print_position(
        RobotPosition(
            tuple(final.joints_deg),
            tuple(final.commanded_joints_deg),
            None if final.world_mm_deg is None else tuple(final.world_mm_deg),
        ),
        False,
    )


def _station_config(args: argparse.Namespace) -> dict[str, Any]:
    """``--config``'s robot safety limits (keyword values of :class:`SafetyLimits`), and its reference
    pose on ``args.reference``; ``to-reference`` without ``--config`` is a usage error."""
    args.reference = None
    args.station = None
    args.latch_file = None
    if args.config is None:
        if args.robot_command == "selftest" and args.sim:
            return {}  # the simulated station's own configuration
        if args.robot_command in _NEEDS_CONFIG or (args.robot_command == "jog" and args.jog_kind == "camera"):
            raise _BadOptionError(
                f"{args.robot_command} needs --config FILE: the station configuration (its [robot] reference"
                " pose and safety limits, the camera's mounting, the data directory keeping the stop latch)"
            )
        if not (args.sim or args.port):
            raise _BadOptionError("give --sim, --port PORT or --config FILE (whose [robot] names the port)")
        return {}
    try:
        station = config.load_config(args.config)
    except config.ConfigurationError as exc:
        raise _BadOptionError(f"--config: {exc}") from None
    if station.robot is None:
        raise _BadOptionError(f"--config {args.config}: no [robot] section (its reference pose and safety)")
    args.reference = tuple(station.robot.reference_joints_deg)
    args.station = station
    args.latch_file = station.robot_latch_file()
    if not (args.sim or args.port):
        args.port = station.robot.options.get("port")
        if not args.port:
            raise _BadOptionError(f"--config {args.config}: its [robot] options name no port; give --port")
    return station.robot_safety()


_NEEDS_CONFIG = frozenset({"to-reference", "acknowledge", "selftest"})


_OPTION_OF_FIELD = {
    "baudrate": "--baud",
    "reply_timeout_s": "--timeout",
    "max_step_deg": "--max-step",
    "stall_timeout_s": "--stall-timeout",
}


def _number(option: str, text: str | None, kind: type[float] | type[int]) -> float | int | None:
    if text is None:
        return None
    try:
        value = kind(text)
    except ValueError:
        raise _BadOptionError(f"{option}: expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise _BadOptionError(f"{option}: expected a finite number, got {text!r}")
    return value


class _BadOptionError(ValueError):
    """An option value that failed validation: one line, exit 2, nothing opened."""


def _one_line(exc: ValidationError) -> str:
    first = exc.errors()[0]
    field = str(first["loc"][-1]) if first["loc"] else "value"
    option = _OPTION_OF_FIELD.get(field, field)
    return f"{option}: {first['msg'].lower()} (got {first.get('input')!r})"


def _check_positionals(args: argparse.Namespace) -> None:
    """argparse skips a positional's type after a second ``--`` (``joint 1 -- --`` gives ``[]``)."""
    expected = {"axis": "AXIS", "degrees": "DEGREES"}
    for name, label in expected.items():
        value = getattr(args, name, None)
        if value is None:
            continue
        if args.robot_command in ("move-joints", "move-camera") and name == "degrees":
            if not (isinstance(value, list) and all(isinstance(v, float) for v in value)):
                raise _BadOptionError(f"{label}: expected six numbers, got {value!r}")
        elif isinstance(value, list | str):
            raise _BadOptionError(f"{label}: expected a number, got {value!r}")


def _settings(args: argparse.Namespace) -> dict[str, Any]:
    """Every option value validated into the driver's settings before anything is opened."""
    _check_positionals(args)
    if args.robot_command == "selftest":
        unknown = sorted(set(args.checks.split(",")) - set(_cli_station.CHECK_NAMES))
        if unknown:
            names = ",".join(_cli_station.CHECK_NAMES)
            raise _BadOptionError(f"--checks: unknown {unknown}; choose from {names}")
    if getattr(args, "calibration", None) is not None:
        from station.calibration import load_kinematics

        try:
            args.calibrated = load_kinematics(args.calibration)
        except (OSError, ValueError) as exc:
            raise _BadOptionError(f"--calibration {args.calibration}: {exc}") from None
    baud = _number("--baud", args.baud, int)
    link: dict[str, Any] = {}
    if baud is not None and not args.sim:
        link["baudrate"] = baud
    timeout = _number("--timeout", args.timeout, float)
    if timeout is not None:
        link["reply_timeout_s"] = timeout
    safety: dict[str, Any] = _station_config(args)
    max_step = _number("--max-step", args.max_step, float)
    if max_step is not None:
        safety["max_step_deg"] = max_step
    motion: dict[str, Any] = {}
    stall = _number("--stall-timeout", args.stall_timeout, float)
    if stall is not None:
        motion["stall_timeout_s"] = stall
    try:
        return {
            "link": LinkSettings.model_validate(link),
            "safety": SafetyLimits.model_validate(safety),
            "motion": MotionSettings.model_validate(motion),
        }
    except ValidationError as exc:
        raise _BadOptionError(_one_line(exc)) from None


_EXIT_OF_SIGNAL = {signal.SIGINT: 130, signal.SIGTERM: 143}


def _supervise(robot: CrsA465, args: argparse.Namespace) -> int:
    """Run the command in a worker thread; on SIGINT/SIGTERM stop the arm, say where it is, exit 130/143."""
    failure: list[BaseException] = []

    def work() -> None:
        try:
            robot.connect()
            _run_command(robot, args)
        except BaseException as exc:  # noqa: BLE001 - handed to the main thread
            failure.append(exc)

    received: list[int] = []

    def on_signal(signum: int, frame: FrameType | None) -> None:
        received.append(signum)

    previous: dict[signal.Signals, Any] = {}
    if threading.current_thread() is threading.main_thread():
        for signum in _EXIT_OF_SIGNAL:
            previous[signum] = signal.signal(signum, on_signal)
    try:
        worker = threading.Thread(target=work, name="station robot", daemon=True)
        worker.start()
        stopped = False
        while worker.is_alive():
            worker.join(0.05)
            if received and not stopped:
                stopped = True
                robot.stop()
        if received:
            name = signal.Signals(received[0]).name
            position = robot.last_position
            if position is None:
                _err(f"{name}: stop sent; the arm's position is unknown (the link was not up)")
            else:
                _err(
                    f"{name}: stop sent; the arm is at joints {_fmt_row(position.joints_deg, 'deg')},"
                    f" commanded {_fmt_row(position.commanded_joints_deg, 'deg')}"
                )
                _print_position(position, args.json)
            return _EXIT_OF_SIGNAL[signal.Signals(received[0])]
        if failure:
            raise failure[0]
        return int(getattr(args, "exit_code", 0))
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def handle(args: argparse.Namespace) -> int:
    """Run one ``station robot`` command; exit code 0, 1 (refused or failed), 2 (bad option value)."""
    try:
        settings = _settings(args)
    except _BadOptionError as exc:
        _err(str(exc))
        return 2
    twin: _Twin | None = None
    robot: CrsA465 | None = None
    try:
        if args.sim and args.robot_command == "selftest":
            robot, twin = _cli_station.open_sim_station(args)
            return _supervise(robot, args)
        if args.sim:
            twin = config.build("controller", "sim", shell=args.shell, app_name=args.app_name)
            port = twin.port
        else:
            port = args.port
        robot = build_robot(
            port, shell=args.shell, app_name=args.app_name, latch_file=args.latch_file, **settings
        )
        if args.robot_command == "acknowledge":  # no link needed: the latch is the station's
            _cli_station.acknowledge(robot)
            _out(json.dumps({"acknowledged": True}) if args.json else "the stop is acknowledged")
            return 0
        return _supervise(robot, args)
    except DeviceError as exc:
        _err(str(exc))
        return 1
    except (config.ConfigurationError, ValueError, RemoteAcknowledgementError) as exc:
        _err(str(exc))
        return 1
    finally:
        if robot is not None:
            robot.close()
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
        help="CRS A465 on a C500C controller: status, where, home, ready, speed, joint, move-joints,"
        " to-reference",
        description="Talk to a C500C controller: a real one, `station sim controller`, or any emulator.",
    )
    target = parser.add_mutually_exclusive_group(required=False)
    target.add_argument("--sim", action="store_true", help="start a fresh controller twin for this call")
    target.add_argument("--port", help="serial port or pyserial URL of the controller (e.g. /dev/ttyS0)")
    parser.add_argument("--baud", default=None, metavar="N", help="baud rate (default 57600)")
    parser.add_argument("--json", action="store_true", help="print JSON")
    parser.add_argument(
        "--config",
        default=None,
        metavar="FILE",
        help="station configuration (TOML): the port, reference pose, the cell's safety limits, the camera's"
        " mounting and the data directory (the stop latch)",
    )
    parser.add_argument(
        "--shell",
        choices=("system", "application"),
        default="system",
        help="controller shell (default system)",
    )
    parser.add_argument("--app-name", default="ash", help="application shell name: its prompt is 'NAME> '")
    parser.add_argument("--max-step", default=None, metavar="DEG", help="largest joint change per call")
    parser.add_argument("--timeout", default=None, metavar="S", help="reply timeout (default 3 s)")
    parser.add_argument(
        "--stall-timeout",
        default=None,
        metavar="S",
        help="fail a motion when nothing has moved this long short of the target (default 3 s)",
    )
    commands = parser.add_subparsers(dest="robot_command", required=True, metavar="COMMAND")
    commands.add_parser(
        "status", help="power, calibration, homing, motion, speed, arm type (armstat and speed)"
    )
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
    camera = commands.add_parser(
        "move-camera",
        help="compensated move: the camera to a pose under a calibrated model (station calibrate --out)",
        description="Move the camera to X Y Z (mm) Z_ROT Y_ROT X_ROT (deg, as a WORLD row) in the calibrated"
        " model's base frame: inverse kinematics with the calibrated model, then joint moves within the"
        " largest joint step, every waypoint checked before the first is sent.",
    )
    camera.add_argument("pose", type=float, nargs=6, metavar="V")
    camera.add_argument("--calibration", required=True, metavar="FILE", help="a calibrated parameter set")
    commands.add_parser(
        "to-reference",
        help="the arm to the station's reference pose from wherever it is (needs --config)",
        description="Take the arm to the reference pose of --config's [robot]: a single move when every"
        " joint is within one step of it, else up through the lift pose (upper arm and forearm upright),"
        " across and down; every move within the largest joint step and checked (limits, step, keep-out)"
        " from the arm's commanded position before the first is sent. Prints the moves and where the arm"
        " is (--json: one object with reference_joints_deg, start, moves, via_lift, final_pose,"
        " at_reference).",
    )
    _cli_station.add_parsers(commands)
    parser.set_defaults(func=handle)


__all__ = ["handle", "register"]
