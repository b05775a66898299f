"""``station table (--sim | --manual) [--config FILE] move X_MM Y_MM``: move the X-Y table through an
operator prompt. With ``--config`` the table is the configuration's ``[table]`` (its driver and options:
travel and origin), so that a target outside the cell's travel is refused before anyone is asked."""

from __future__ import annotations

import argparse
import json
import sys
import threading

from station import config
from station.commands._common import finite_float
from station.commands._parsing import SubParsers
from station.devices import DeviceError
from station.prompts import PromptBroker, PromptEvent


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "table",
        help="move the X-Y table (the operator turns the micrometers when prompted)",
        description="Move the manual micrometer X-Y table to X_MM, Y_MM (table axes, mm). The move "
        "becomes a prompt ('set X to 0.0100 in, Y to 0.0000 in, then confirm') answered by the "
        "simulated operator (--sim) or at this terminal (--manual).",
    )
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--sim", action="store_true", help="a simulated table and operator")
    who.add_argument("--manual", action="store_true", help="the real table; answer the prompt here")
    p.add_argument(
        "--timeout",
        type=finite_float("--timeout", positive=True),
        default=None,
        help="give up after this many seconds (a finite number above 0)",
    )
    p.add_argument("--json", action="store_true", help="print the confirmed position as JSON")
    p.add_argument("--config", metavar="FILE", help="station configuration: its [table] (travel, origin)")
    tsub = p.add_subparsers(dest="table_command", required=True, metavar="COMMAND")
    move = tsub.add_parser("move", help="move to X_MM Y_MM")
    move.add_argument("x_mm", type=finite_float("X_MM"), metavar="X_MM")
    move.add_argument("y_mm", type=finite_float("Y_MM"), metavar="Y_MM")
    p.set_defaults(func=lambda args: run(args, parser=move))


def run(args: argparse.Namespace, parser: argparse.ArgumentParser | None = None) -> int:
    # every input was checked by argparse (finite numbers, exit 2); the travel is checked by the
    # table before it raises any prompt (exit 1)
    for name in ("x_mm", "y_mm"):
        if not isinstance(getattr(args, name), float):  # argparse skips ``type`` after a second "--"
            message = f"{name.upper()} must be a finite number, got {getattr(args, name)!r}"
            if parser is None:
                raise SystemExit(f"station table: {message}")
            parser.error(message)
    broker = PromptBroker()

    def show(event: PromptEvent) -> None:
        if event.kind == "opened":
            print(f"station table: {event.prompt.message}", file=sys.stderr)
        elif event.answer is not None:
            by = f" by {event.answer.by}" if event.answer.by else ""
            print(f"station table: {event.answer.outcome.value}{by}", file=sys.stderr)

    stop = threading.Event()
    helper: threading.Thread | None = None
    operator = None
    try:
        if args.sim:
            operator = config.build("operator", "sim", broker=broker)
        else:
            client = config.build("prompt_client", "terminal", broker=broker)
            helper = threading.Thread(target=client.serve, args=(stop,), daemon=True)
            helper.start()
        broker.subscribe(show)
        driver, options = "manual", {}
        if args.config is not None:
            station = config.load_config(args.config)
            if station.table is None:
                raise config.ConfigurationError(f"--config {args.config}: no [table] section")
            driver, options = station.table.driver, dict(station.table.options)
        table = config.build("table", driver, broker=broker, **options)
        position = table.move_to(args.x_mm, args.y_mm, timeout_s=args.timeout)
    except (DeviceError, ValueError) as exc:
        print(f"station table: {exc}", file=sys.stderr)
        return 1
    finally:
        stop.set()
        if operator is not None:
            operator.close()
    if args.json:
        print(json.dumps({"x_mm": position.x_mm, "y_mm": position.y_mm}))
    else:
        print(f"table at X {position.x_mm:.5f} mm, Y {position.y_mm:.5f} mm")
    return 0
