"""``make bench``, the station's half: the record, the session runner and the simulated arm.

* the record's write rate and bytes per capture (``bench.record_bench``, 1,000 captures);
* the runner's software overhead per capture-move-return cycle against the arm's motion time, with the
  controller twin at real time, and resident memory at capture 1,000 and 10,000 of a long session
  (``bench.sessions_bench``);
* the simulated Table 2 beside the seed's (``bench.table2``: the sim arm's error model, per joint and the
  two sequences, over seeds).

Written to ``bench/results/station.json``. ``python -m bench.station_bench [--quick]`` (quick: 2,000
captures instead of 10,000, fewer seeds).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from bench import record_bench, sessions_bench, table2

RESULTS = Path(__file__).parent / "results" / "station.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a shorter run (2,000 captures, 5 seeds)")
    args = parser.parse_args()
    captures = 2_000 if args.quick else 10_000
    out: dict[str, Any] = {}

    print("record: 1,000 captures (PNG, fsync, rows) ...", flush=True)
    rec = record_bench.run(captures=1_000)
    out["record"] = rec
    print(json.dumps(rec, indent=2), flush=True)

    print("session overhead at real time (twin time_scale=1) ...", flush=True)
    over = sessions_bench.overhead(cycles=10)
    out["overhead"] = over
    motion_ms, software_ms = over["motion_s_per_cycle"] * 1000, over["software_s_per_cycle"] * 1000
    print(
        f"  per cycle: motion {motion_ms:.0f} ms, station software {software_ms:.0f} ms "
        f"({over['software_over_motion'] * 100:.1f} % of the motion; goal under 5 %), "
        f"simulated camera {over['camera_s_per_cycle'] * 1000:.0f} ms",
        flush=True,
    )

    print(f"session memory over {captures} captures ...", flush=True)
    mem = sessions_bench.memory(captures=captures)
    out["memory"] = mem
    print(
        f"  RSS at capture 1,000: {mem['rss_mb_at_1000']:.1f} MB; at {captures}: "
        f"{mem[f'rss_mb_at_{captures}']:.1f} MB (growth {mem['rss_growth_mb']:+.1f} MB; budget 50 MB); "
        f"{mem['captures_per_s']:.1f} captures/s",
        flush=True,
    )

    print("simulated Table 2 (the sim arm's error model) ...", flush=True)
    t2 = table2.run(seeds=5 if args.quick else 20)
    out["table2"] = t2
    print(table2.format_table(t2), flush=True)

    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=2, default=str) + "\n", encoding="utf-8")
    print(f"written to {RESULTS}")


if __name__ == "__main__":
    main()
