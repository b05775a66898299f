"""``make bench``, an archive re-analysed in one run (issue 24, item 3): a lab archive of small validation
sessions recorded on the simulated station, then

* one ``sweep`` session over the whole archive, selected by filter (``select={"kind": "validation"}``):
  the seed's Table 1 trials, each on every session, ranked over all of them; its report (Table 1 over
  the archive and the per-session table) is written, and Table 1 printed;
* one ``reanalyse`` session of the same selection: every capture measured again and each session
  analysed as its own kind (its results compared with the stored ones: same parameters and software,
  the same numbers).

Reported: wall seconds and the CPU seconds of this process and of every process it started (sampled
while they live) of each run, frames measured,
frames per second; the archive's recording time apart (it is the set-up, not what is measured). Written
to ``bench/results/archive.json``. ``python -m bench.archive_bench [--sessions N] [--steps-per-side K]
[--jobs J]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import psutil

from bench.timing import cores
from station.commands.sessions import write_session_report
from station.compute import ComputeSpec
from station.record import Record
from station.session import SessionOutcome, run_session

RESULTS = Path(__file__).parent / "results" / "archive.json"
log = logging.getLogger("bench.archive")


class CpuMeter:
    """CPU seconds of this process and of every process it starts (the pool's, the fork server's),
    sampled every ``interval`` s by a thread: a pool's processes end with the session, before a
    reading after it could see them (a process's last ``interval`` is missed)."""

    def __init__(self, interval: float = 0.1) -> None:
        self._interval = interval
        self._me = psutil.Process()
        self._first: dict[int, float] = {}
        self._last: dict[int, float] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="cpu-meter", daemon=True)

    def _sample(self, *, baseline: bool = False) -> None:
        """Each process's CPU now; a process first seen after the baseline started since (from 0)."""
        for proc in [self._me, *self._me.children(recursive=True)]:
            with contextlib.suppress(psutil.Error):
                t = sum(proc.cpu_times()[:2])
                self._first.setdefault(proc.pid, t if baseline else 0.0)
                self._last[proc.pid] = t

    def _run(self) -> None:
        while not self._stop.wait(self._interval):
            self._sample()

    def __enter__(self) -> CpuMeter:
        self._sample(baseline=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        self._sample()

    @property
    def seconds(self) -> float:
        return sum(self._last[pid] - self._first[pid] for pid in self._last)


def _timed(run: Callable[[], SessionOutcome]) -> tuple[SessionOutcome, float, float]:
    """The outcome, wall and CPU seconds (all our processes) of a session run."""
    t0 = time.perf_counter()
    with CpuMeter() as cpu:
        outcome = run()
    return outcome, time.perf_counter() - t0, cpu.seconds


def build_archive(data: Path, sessions: int, steps_per_side: int) -> list[str]:
    """``sessions`` validations of ``steps_per_side`` on the simulated station, each its own pose set."""
    ids = []
    for _ in range(sessions):
        out = run_session("validation", sim=True, params={"steps_per_side": steps_per_side}, data=data)
        if out.state != "succeeded":
            raise SystemExit(f"recording the archive failed: {out.error}")
        ids.append(str(out.id))
    return ids


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("--sessions", type=int, default=50, help="validation sessions in the archive")
    ap.add_argument("--steps-per-side", type=int, default=2, help="each validation's size (2: 8 positions)")
    ap.add_argument("--jobs", type=int, default=cores(), help="the local pool's processes")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    select = {"kind": "validation"}
    spec = ComputeSpec(jobs=args.jobs)
    with tempfile.TemporaryDirectory(prefix="archive-bench-") as tmp:
        data = Path(tmp) / "data"
        t0 = time.perf_counter()
        ids = build_archive(data, args.sessions, args.steps_per_side)
        recorded_s = time.perf_counter() - t0
        with Record(data) as record:
            positions = sum(len(record.captures(i)) for i in ids)

        sweep, sweep_wall, sweep_cpu = _timed(
            lambda: run_session("sweep", params={"select": select}, data=data, jobs=args.jobs, compute=spec)
        )
        if sweep.state != "succeeded":
            raise SystemExit(f"the sweep over the archive failed: {sweep.error}")
        results = sweep.results
        trials = len(results["trials"])
        report = write_session_report(str(sweep.id), data, None, Path(tmp) / "report")
        again, again_wall, again_cpu = _timed(
            lambda: run_session(
                "reanalyse", params={"select": select}, data=data, jobs=args.jobs, compute=spec
            )
        )
        if again.state != "succeeded":
            raise SystemExit(f"the re-analysis of the archive failed: {again.error}")
        with Record(data) as record:
            same = sum(
                _same(s["validation"], record.get_session(s["source_session"]).results or {})
                for s in again.results["sessions"]
            )
        table_1 = report.tables.get("sweep", "")
        if "sweep_sessions" not in report.tables:
            raise SystemExit("the sweep's report has no per-session table")

    swept = positions * trials
    doc: dict[str, Any] = {
        "sessions": args.sessions,
        "positions": positions,
        "jobs": args.jobs,
        "recording_s": round(recorded_s, 2),
        "sweep": {
            "trials": trials,
            "frames": swept,
            "wall_s": round(sweep_wall, 2),
            "cpu_s": round(sweep_cpu, 2),
            "frames_per_s": round(swept / sweep_wall, 1),
            "cpu_ms_per_frame": round(1000.0 * sweep_cpu / swept, 2),
            "best": results["best"],
            "ranked_over": len(results["sessions"]),
        },
        "reanalyse": {
            "frames": positions,
            "wall_s": round(again_wall, 2),
            "cpu_s": round(again_cpu, 2),
            "frames_per_s": round(positions / again_wall, 1),
            "cpu_ms_per_frame": round(1000.0 * again_cpu / positions, 2),
            "sessions_identical_to_stored": same,
        },
    }
    print(f"archive: {args.sessions} validations, {positions} position frames ({recorded_s:.1f} s to record)")
    print(
        f"sweep over the archive: {trials} trials x {args.sessions} sessions = {swept} frames in "
        f"{sweep_wall:.1f} s wall, {sweep_cpu:.1f} s CPU ({swept / sweep_wall:.0f} frames/s, "
        f"{1000 * sweep_cpu / swept:.2f} ms CPU/frame), {args.jobs} jobs; best trial {results['best']}"
    )
    print(
        f"re-analysis of the archive: {positions} frames in {again_wall:.1f} s wall, {again_cpu:.1f} s CPU; "
        f"{same} of {args.sessions} sessions' results identical to the stored ones"
    )
    print(table_1)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"written to {args.out}")
    return 0 if same == args.sessions and doc["sweep"]["ranked_over"] == args.sessions else 1


def _same(redone: dict[str, Any], stored: dict[str, Any]) -> bool:
    """A source's results measured again equal its stored ones, bit for bit."""
    return redone == stored


if __name__ == "__main__":
    raise SystemExit(main())
