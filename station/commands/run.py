"""``station run KIND`` and ``station run --resume ID``: one session, from the command line.

``--param NAME=VALUE`` sets a plan parameter (the value parsed as JSON, else taken as a string);
``--set NAME=VALUE`` a measurement parameter. With ``--json`` the last line on stdout is
``{"id", "kind", "state", "results"}``. Exit 0 when the session succeeded, 1 for any other final state,
2 for usage errors. Ctrl-C (or SIGTERM) aborts: the robot is stopped through its latched stop, the
session is recorded as aborted with everything captured so far.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import typing
from collections.abc import Sequence
from typing import Any

from station.batch import max_jobs
from station.commands._common import add_compute_options, compute_spec
from station.commands._parsing import SubParsers, add_record_options
from station.config import ConfigurationError
from station.devices import DeviceError
from station.kinds import KIND_NAMES, get_plan, summary
from station.plans import PlanError
from station.record import EventRow, RecordError, SessionLockError
from station.resources import dumps
from station.runner import SessionError, SessionRunner
from station.scale_calibration import ScaleCalibrationError
from station.session import run_session
from station.vision import parse_assignments


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "run",
        help="run a session: validation, repeatability, calibration, sweep or reanalyse",
        description="Run one session on the simulated station (--sim) or a configured one (--config), "
        "record everything, and print its results. sweep and reanalyse need no station.",
    )
    p.add_argument("kind", nargs="?", choices=KIND_NAMES, help="the session's plan")
    p.add_argument("--resume", metavar="ID", help="continue an interrupted session after its last step")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--sim", action="store_true", help="the simulated station")
    where.add_argument("--config", metavar="FILE", help="a station configuration (TOML)")
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="plan parameter, VALUE as JSON or a plain string (e.g. --param cycles=10, "
        "--param 'sequences={\"S1\": [[...], [...]]}')",
    )
    p.add_argument(
        "--set",
        dest="assignments",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="measurement parameter (as in station measure)",
    )
    p.add_argument(
        "-j",
        "--jobs",
        type=int,  # bounded in run(), so that --json can still print its outcome object
        default=None,
        help=f"local worker processes for sweep and reanalyse, 1 to {max_jobs()} (default 1)",
    )
    add_compute_options(p)
    p.add_argument("--json", action="store_true", help="print the outcome as one JSON object (last line)")
    p.add_argument("--report", action="store_true", help="write the session's report and print where")
    add_record_options(p)
    p.set_defaults(func=lambda args: run(p, args))


def parse_params(
    parser: argparse.ArgumentParser, items: Sequence[str], text: frozenset[str] = frozenset()
) -> dict[str, Any]:
    """``--param NAME=VALUE`` items: VALUE as JSON, else as the string typed; a parameter named in
    ``text`` (the plan's string parameters) is always the string typed."""
    out: dict[str, Any] = {}
    for item in items:
        name, sep, raw = item.partition("=")
        name = name.strip()
        if not sep or not name:
            parser.error(f"--param {item!r}: expected NAME=VALUE")
        try:
            value: Any = raw if name in text else json.loads(raw)
        except json.JSONDecodeError:
            value = raw
        out[name] = value
    return out


def text_params(kind: str | None) -> frozenset[str]:
    """The string parameters of ``kind``'s plan: a session id such as ``505e3210`` is a number to JSON."""
    if kind is None or kind not in KIND_NAMES:
        return frozenset()
    fields = get_plan(kind).Params.model_fields
    return frozenset(
        name
        for name, info in fields.items()
        if info.annotation is str or str in typing.get_args(info.annotation)
    )


class _Progress:
    """A progress bar on stderr when it is a terminal; one line per state change otherwise."""

    def __init__(self) -> None:
        self._bar: Any = None
        self._tty = sys.stderr.isatty()

    def __call__(self, event: EventRow) -> None:
        if event.type == "state":
            if self._bar is not None:
                self._bar.set_postfix_str(event.data["state"])
            else:
                print(f"station run: {event.data['state']}", file=sys.stderr)
        elif event.type == "step_finished" and self._tty:
            p = event.data["progress"]
            if self._bar is None:
                from tqdm import tqdm

                self._bar = tqdm(total=p["total"], file=sys.stderr, unit="step")
            self._bar.n = p["done"]
            self._bar.refresh()
        elif event.type in ("error", "warning"):
            print(f"station run: {event.type}: {event.data.get('message')}", file=sys.stderr)
        elif event.type == "prompt_raised" and not self._tty:
            print(f"station run: operator: {event.data['message']}", file=sys.stderr)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def failed_outcome(
    kind: str | None, session_id: str | None, error: str, results: dict[str, Any] | None = None
) -> str:
    """``--json``'s last line when the session could not run or its outcome could not be recorded:
    the outcome object with state ``failed`` and the error (``id`` null when no session was made)."""
    doc = {"id": session_id, "kind": kind, "state": "failed", "results": results or {}, "error": error}
    return json.dumps(doc, default=str)


def run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    def usage(message: str) -> None:
        if args.json:
            print(failed_outcome(args.kind, args.resume, message))
        parser.error(message)

    if (args.kind is None) == (args.resume is None):
        usage("give a session kind, or --resume ID (not both)")
    if args.jobs is not None and not 1 <= args.jobs <= max_jobs():
        usage(f"--jobs must be from 1 to {max_jobs()}, got {args.jobs}")
    try:
        compute = compute_spec(parser, args, jobs=1)
        params = parse_params(parser, args.param, text_params(args.kind))
    except SystemExit:
        if args.json:
            print(failed_outcome(args.kind, args.resume, "a usage error (see above)"))
        raise
    try:
        assignments = dict(parse_assignments(args.assignments))
    except ValueError as exc:
        usage(str(exc))
    progress = _Progress()
    runners: list[SessionRunner] = []
    signals: dict[int, int] = {signal.SIGINT: 130, signal.SIGTERM: 143}
    received: list[int] = []

    def on_signal(signum: int, frame: object) -> None:
        received.append(signum)
        for r in runners:
            r.abort(f"aborted by {signal.Signals(signum).name}")

    outcome_box: list[Any] = []
    error_box: list[BaseException] = []

    def work() -> None:
        try:
            outcome_box.append(
                run_session(
                    args.kind,
                    sim=args.sim,
                    config=args.config,
                    params=params,
                    assignments=assignments,
                    data=args.data,
                    database=args.database,
                    resume=args.resume,
                    jobs=args.jobs or 1,
                    compute=compute,
                    on_event=progress,
                    on_runner=runners.append,
                )
            )
        except BaseException as exc:  # noqa: BLE001 - handed to the main thread below
            error_box.append(exc)

    # The session runs in a worker thread; the main thread only waits, so that Ctrl-C's handler can
    # call abort() (robot.stop() on the serial link) without interrupting the runner mid-exchange.
    worker = threading.Thread(target=work, name="station-run")
    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {s: signal.signal(s, on_signal) for s in signals}
    try:
        worker.start()
        while worker.is_alive():
            worker.join(0.2)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    if error_box:
        progress.close()
        failure = error_box[0]
        if args.json:  # whatever failed, the last line is the outcome object (issue 18)
            runner = runners[-1] if runners else None
            print(
                failed_outcome(
                    args.kind or (runner.plan.name if runner is not None else None),
                    (runner.session_id if runner is not None else None) or args.resume,
                    str(failure) or type(failure).__name__,
                    runner.results if runner is not None else None,
                )
            )
        if isinstance(failure, PlanError | ConfigurationError | ScaleCalibrationError):
            print(f"station run: {failure}", file=sys.stderr)
            return 2
        if isinstance(failure, SessionLockError | SessionError | RecordError | DeviceError | OSError):
            print(f"station run: {failure}", file=sys.stderr)
            return signals[received[0]] if received else 1
        raise failure
    outcome = outcome_box[0]
    progress.close()
    if args.report:
        from station.commands.sessions import write_session_report

        try:
            files = write_session_report(outcome.id, args.data, args.database)
            print(f"report: {files.html}", file=sys.stderr if args.json else sys.stdout)
        except (RecordError, OSError) as exc:
            print(f"station run: the report could not be written: {exc}", file=sys.stderr)
    if args.json:
        print(dumps(outcome))
    else:
        print(f"session {outcome.id} ({outcome.kind}): {outcome.state}")
        if outcome.error:
            print(f"  {outcome.error}")
        if outcome.state in ("failed", "aborted", "stopped", "interrupted"):
            print(f"  continue it after its last completed step: station run --resume {outcome.id}")
        print(summary(outcome.kind, outcome.results))
    if received:
        return signals[received[0]]
    return 0 if outcome.state == "succeeded" else 1
