"""A scripted repeatability session (ISO 9283 RP per joint), from Python.

    python examples/repeatability.py --sim                      # the simulated station
    python examples/repeatability.py --config station.toml      # a real one
    python examples/repeatability.py --sim --cycles 10 --joints 1 2 3

It runs the seed's protocol (joint j moved by delta and back, captured at the reference pose after each
return), prints each test's RP with its 95 % interval next to the seed's Table 2, and writes the report
(tables, Figures 16-17, HTML). Ctrl-C aborts the session cleanly (the arm is stopped, the record kept).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from station.kinds.repeatability.plan import SEED_TABLE2_MM
from station.runner import SessionRunner
from station.session import SessionOutcome, run_session


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--sim", action="store_true", help="the simulated station")
    where.add_argument("--config", help="a station configuration file (TOML)")
    parser.add_argument("--cycles", type=int, default=30)
    parser.add_argument("--joints", type=int, nargs="+", default=[1, 2, 3, 4, 5, 6])
    parser.add_argument("--delta-deg", type=float, default=10.0)
    parser.add_argument("--data", help="data directory (default $STATION_DATA or ./station-data)")
    args = parser.parse_args()

    runners: list[SessionRunner] = []
    outcome_box: list[SessionOutcome] = []

    def work() -> None:
        outcome_box.append(
            run_session(
                "repeatability",
                sim=args.sim,
                config=args.config,
                params={"cycles": args.cycles, "joints": args.joints, "delta_deg": args.delta_deg},
                data=args.data,
                on_runner=runners.append,
            )
        )

    def on_interrupt(signum: int, frame: object) -> None:
        for r in runners:
            r.abort("Ctrl-C in the example script")

    signal.signal(signal.SIGINT, on_interrupt)
    worker = threading.Thread(target=work)
    worker.start()
    while worker.is_alive():
        worker.join(0.2)
    if not outcome_box:
        return 1
    outcome = outcome_box[0]
    print(f"session {outcome.id}: {outcome.state}")
    for test, entry in outcome.results.get("tests", {}).items():
        if "rp_mm" not in entry:
            print(f"  {test}: {entry.get('error')}")
            continue
        lo, hi = entry["rp_ci95_mm"]
        seed = SEED_TABLE2_MM.get(test)
        seed_text = f"   seed {seed:.5f}" if seed is not None else ""
        print(f"  {test}: RP {entry['rp_mm']:.5f} mm (95 % {lo:.5f}-{hi:.5f}){seed_text}")

    from station.commands.sessions import write_session_report

    files = write_session_report(outcome.id, args.data, None)
    print(f"report: {files.html}")
    return 0 if outcome.state == "succeeded" else 1


if __name__ == "__main__":
    sys.exit(main())
