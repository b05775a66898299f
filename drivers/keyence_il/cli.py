"""``station zsensor``: read the Z distance sensor (a real DL-RS1A + IL head, or a fresh twin).

    station zsensor (--sim | --port PORT [--baud N]) [--timeout S] [--json] read [--count N]
    station zsensor (--sim | --port PORT) [--json] status
    station zsensor --config FILE [--json] read|status     (the configuration's [distance_sensor])

``read`` prints one distance (mm) per line, or ``{"ok": true, "z_mm": ...}`` with ``--json``; a reading
the sensor cannot give prints ``{"ok": false, "error": ..., "code": "out_of_range" | "alarm"}`` (the
error also on stderr) and the command exits 1 after the count. Link failures exit 1 at once; bad
option values 2. ``--sim`` starts a twin through the device registry (drivers never import ``sim``):
a default simulated world, the camera in focus, so it reads about 68 mm.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from pydantic import ValidationError

from drivers.keyence_il import open_distance_sensor
from station import config
from station._pydantic import problems
from station.devices import DeviceError, OutOfRangeError, SensorAlarmError


def _out(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _err(text: str) -> None:
    sys.stderr.write(f"station zsensor: {text}\n")


def _count(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--count must be a whole number, got {text!r}") from None
    if not 1 <= n <= 100000:
        raise argparse.ArgumentTypeError(f"--count must be 1 to 100000, got {n}")
    return n


def _read(sensor: Any, args: argparse.Namespace) -> int:
    failed = 0
    for _ in range(args.count):
        try:
            z = sensor.read_mm()
        except (OutOfRangeError, SensorAlarmError) as exc:
            failed += 1
            code = "out_of_range" if isinstance(exc, OutOfRangeError) else "alarm"
            _err(str(exc))
            if args.json:
                _out(json.dumps({"ok": False, "error": str(exc), "code": code}))
            continue
        _out(json.dumps({"ok": True, "z_mm": z}) if args.json else f"{z:.3f}")
    return 1 if failed else 0


def handle(args: argparse.Namespace) -> int:
    """Run one ``station zsensor`` command; exit 0, 1 (no reading, device failure) or 2 (bad option)."""
    link: dict[str, Any] = {}
    if args.timeout is not None:
        link["reply_timeout_s"] = args.timeout
    twin: Any = None
    sensor: Any = None
    try:
        options: dict[str, Any] = {}
        if args.config is not None:
            station = config.load_config(args.config)
            if station.distance_sensor is None:
                _err(f"--config {args.config}: no [distance_sensor] section")
                return 2
            options = dict(station.distance_sensor.options)
            link = {**dict(options.pop("link", None) or {}), **link}
        if args.sim:
            twin = config.build("distance_sensor_twin", "sim")
            port = twin.port
        else:
            port = args.port or options.pop("port", None)
            if not port:
                _err("give --sim, --port PORT, or --config FILE whose [distance_sensor] names the port")
                return 2
        options.pop("port", None)
        try:
            sensor = open_distance_sensor(port, link=link, baudrate=args.baud, **options)
        except ValidationError as exc:
            _err(f"bad option: {problems(exc, 'settings')}")
            return 2
        sensor.connect()
        if args.zsensor_command == "read":
            return _read(sensor, args)
        status = sensor.status()
        if args.json:
            _out(json.dumps({"state": status.state, "ok": status.ok, "text": status.text}))
        else:
            _out(f"{status.state}: {status.text}")
        return 0
    except (DeviceError, config.ConfigurationError) as exc:
        _err(str(exc))
        return 1
    finally:
        if sensor is not None:
            sensor.close()
        if twin is not None:
            twin.close()


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg,unused-ignore]
    """Add ``station zsensor`` to the station's sub-commands."""
    parser = sub.add_parser(
        "zsensor",
        help="Z distance sensor (Keyence IL via DL-RS1A): read, status",
        description="Read the Z distance sensor: a real DL-RS1A on a serial port, or a fresh twin.",
    )
    target = parser.add_mutually_exclusive_group(required=False)
    target.add_argument("--sim", action="store_true", help="start a fresh sensor twin for this call")
    target.add_argument("--port", help="serial port or pyserial URL of the DL-RS1A (e.g. /dev/ttyUSB0)")
    parser.add_argument("--baud", type=int, default=None, metavar="N", help="baud rate (default 38400)")
    parser.add_argument(
        "--timeout", type=float, default=None, metavar="S", help="reply timeout (default 1 s)"
    )
    parser.add_argument("--json", action="store_true", help="print JSON, one object per line")
    parser.add_argument(
        "--config", metavar="FILE", help="station configuration: its [distance_sensor] (port, head, link)"
    )
    commands = parser.add_subparsers(dest="zsensor_command", required=True, metavar="COMMAND")
    read = commands.add_parser("read", help="read distances (mm)")
    read.add_argument("--count", type=_count, default=1, metavar="N", help="how many readings (default 1)")
    commands.add_parser("status", help="ok, out_of_range or alarm, with the sensor's reading")
    parser.set_defaults(func=handle)
