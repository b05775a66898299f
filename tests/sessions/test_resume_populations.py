"""Resume never mixes populations (issue 19, finding 2 and item 4).

A repeatability session killed (SIGKILL of a real process) in the middle of a test, and resumed after the
artifact was knocked 50 um on its table while the station was down (in the simulated world: its truth),
reruns the interrupted test from its start, warm-up included: that test's RP is of one population, and
matches the RP of the same session run without interruption within that session's bootstrap interval
(pooling the 13 cycles before the kill with the 11 after it, as the station did, gave 0.046 mm against
an interval of 0.013-0.022 mm; rerun, 0.01798 mm against the uninterrupted 0.01797 mm). The interrupted
attempt's captures stay in the record, marked abandoned, and never enter RP. (The runner's test on the
fakes checks that a test completed before the interruption is not run again.)
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from station.record import Record
from station.runner import SessionRunner
from station.session import run_session
from tests.sessions.test_cli_sessions import STATION

PARAMS = {"cycles": 24, "warmup_cycles": 2, "joints": [2]}


def kill_after(data: Path, done_steps: int) -> str:
    """Start the repeatability session in a process of its own and SIGKILL it once ``done_steps`` steps
    are done; the session's id."""
    args = [arg for name, value in PARAMS.items() for arg in ("--param", f"{name}={value}")]
    proc = subprocess.Popen(
        [*STATION, "run", "repeatability", "--sim", *args, "--data", str(data), "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if (data / "record.sqlite").exists():
                with Record(data) as rec:
                    rows = rec.list_sessions()
                    if rows and sum(s.state == "done" for s in rec.steps(rows[0].id)) >= done_steps:
                        os.kill(proc.pid, signal.SIGKILL)
                        proc.wait(30)
                        return rows[0].id
            time.sleep(0.02)
        raise AssertionError("the session did not get going")
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def knock_the_table(runner: SessionRunner) -> None:
    """While the station was down, the table was knocked: the artifact now sits 50 um off in x."""
    assert runner.devices is not None
    runner.devices.truth.world.set_table_readings(0.050, 0.0)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_killed_and_resumed_repeatability_matches_the_uninterrupted_session(tmp_path: Path) -> None:
    whole = run_session("repeatability", sim=True, params=PARAMS, data=tmp_path / "whole")
    assert whole.state == "succeeded", whole.error
    reference = whole.results["tests"]["J2"]
    lo, hi = reference["rp_ci95_mm"]

    data = tmp_path / "killed"
    sid = kill_after(data, 16)  # J2's reference, warm-ups and 13 of its 24 cycles
    with Record(data) as rec:
        before = {c.id for c in rec.captures(sid)}
    resumed = run_session(resume=sid, sim=True, data=data, on_runner=knock_the_table)
    assert resumed.state == "succeeded", resumed.error
    test = resumed.results["tests"]["J2"]
    assert test["n_cycles"] == 24
    assert test["partial"] is False
    assert lo <= test["rp_mm"] <= hi, (
        f"resumed RP {test['rp_mm']:.5f} mm outside the uninterrupted session's 95 % interval "
        f"[{lo:.5f}, {hi:.5f}] (its RP {reference['rp_mm']:.5f} mm)"
    )
    with Record(data) as rec:
        after = rec.captures(sid)
        events = rec.events(sid)
    assert before <= {c.id for c in after}  # nothing captured before the kill was lost
    # J2 ran again from its start after the resume: its reference, warm-ups and every cycle
    rerun = [c for c in after if c.meta.get("run") == 1]
    assert next(c.meta["role"] for c in rerun) == "reference"
    assert sorted(c.meta["cycle"] for c in rerun if c.meta["role"] == "cycle") == list(range(24))
    # the interrupted attempt's J2 captures are marked abandoned in the record
    abandoned = [e for e in events if e.type == "abandoned"]
    assert len(abandoned) == 1
    assert set(abandoned[0].data["captures"]) == before
    assert "J2" in abandoned[0].data["reason"]
