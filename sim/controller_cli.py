"""``station sim controller``: run a C500C controller twin on a pty and print the path to open.

The path goes to stdout on one line (or as ``{"port": ...}`` with ``--json``) as soon as the twin
serves; the twin runs until SIGINT or SIGTERM. Several programs and ``station robot --port PATH``
calls can then share it, one at a time.
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
import threading
from types import FrameType
from typing import Any

from pydantic import ValidationError

from sim.controller import ControllerTwin, TwinSettings, parse_fault

log = logging.getLogger(__name__)


def handle(args: argparse.Namespace) -> int:
    """Serve one twin until interrupted."""
    options: dict[str, Any] = {
        "shell": args.shell,
        "app_name": args.app_name,
        "time_scale": args.time_scale,
        "seed": args.seed,
        "motion_blocks": args.blocking,
        "ctrl_c_stops": args.ctrl_c_stops,
        "power": not args.power_off,
        "homed": not args.not_homed,
        "link": args.link,
    }
    if args.repeat_sigma is not None:
        options["repeat_sigma_deg"] = args.repeat_sigma
    try:
        options["faults"] = tuple(parse_fault(spec) for spec in args.fault)
        settings = TwinSettings.model_validate(options)
    except (ValidationError, ValueError) as exc:
        sys.stderr.write(f"station sim controller: {exc}\n")
        return 2
    done = threading.Event()

    def _stop(signum: int, frame: FrameType | None) -> None:
        done.set()

    previous = signal.signal(signal.SIGTERM, _stop)
    twin = ControllerTwin(settings).start()
    try:
        payload = json.dumps({"port": twin.port, "pty": twin.pty_path}) if args.json else twin.port
        sys.stdout.write(payload + "\n")
        sys.stdout.flush()
        while not done.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        twin.close()
        signal.signal(signal.SIGTERM, previous)
    return 0


def register(sim_sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg,unused-ignore]
    """Add ``station sim controller``."""
    parser = sim_sub.add_parser(
        "controller", help="run a simulated C500C controller on a pty and print its path", description=__doc__
    )
    parser.add_argument("--shell", choices=("system", "application"), default="system")
    parser.add_argument("--app-name", default="ash", help="application shell name (prompt 'NAME> ')")
    parser.add_argument("--time-scale", type=float, default=1.0, help="run motions this many times faster")
    parser.add_argument("--seed", type=int, default=None, help="seed of the repeatability error")
    parser.add_argument(
        "--repeat-sigma", type=float, default=None, metavar="DEG", help="random error per joint"
    )
    parser.add_argument(
        "--blocking",
        action="store_true",
        help="the prompt returns when a motion ends (default: at once, as the firmware does)",
    )
    parser.add_argument(
        "--ctrl-c-stops",
        action="store_true",
        help="Ctrl-C stops a motion (default: ignored, only Ctrl-Z halts)",
    )
    parser.add_argument("--power-off", action="store_true", help="start with arm power off")
    parser.add_argument("--not-homed", action="store_true", help="start not homed")
    parser.add_argument(
        "--link", default=None, metavar="PATH", help="keep a symlink at PATH to the current pty"
    )
    parser.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="KIND@N[:VALUE]",
        help="garble, drop, error, disconnect, slow or servo on the Nth command (repeatable)",
    )
    parser.add_argument("--json", action="store_true", help='print {"port": ..., "pty": ...}')
    parser.set_defaults(func=handle)


__all__ = ["handle", "register"]
