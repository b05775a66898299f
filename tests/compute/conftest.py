"""Frames for the compute backends' tests, rendered once and measured once in this process (the reference
every backend must reproduce bit for bit), and a stored session to re-analyse."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from sim.imageset import render_random_set
from station.batch import measure_file
from station.record import Record
from station.session import run_session
from station.vision import MeasureParams

PARAMS = MeasureParams()


@pytest.fixture(scope="session")
def frames(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """48 distinct 640x480 frames of the nominal preset (PNG, as the record stores them)."""
    root = render_random_set(tmp_path_factory.mktemp("frames") / "set", count=48, seed=5)
    return sorted(root.glob("*.png"))


@pytest.fixture(scope="session")
def reference(frames: list[Path]) -> list[str]:
    """Each frame's ``station measure --json`` line, measured here, one frame at a time."""
    return [json.dumps(measure_file(f, PARAMS).to_json()) for f in frames]


@dataclass(frozen=True)
class StoredSession:
    """A validation session recorded on the simulated station: what a re-analysis reads."""

    data: Path
    id: str
    results: dict[str, Any]


@pytest.fixture(scope="session")
def stored(tmp_path_factory: pytest.TempPathFactory) -> StoredSession:
    data = tmp_path_factory.mktemp("record") / "data"
    outcome = run_session("validation", sim=True, params={"steps_per_side": 2}, data=data)
    assert outcome.state == "succeeded", outcome.error
    return StoredSession(data, outcome.id, outcome.results)


def measured(data: Path, session_id: str) -> list[dict[str, Any]]:
    """A session's stored measurements, in order."""
    record = Record(data)
    try:
        return [m.result for m in record.measurements(session_id)]
    finally:
        record.close()


def same_results(redone: dict[str, Any], original: dict[str, Any]) -> bool:
    """A re-analysis' results equal the source's, bit for bit, but for where its scale estimate came
    from (the reanalysis names the source session) and the controller's self-test, which the session
    that drove the arm carries (``station.selftest_status``), not an analysis of its images."""
    a, b = dict(redone), dict(original)
    b.pop("selftest", None)
    b["checks"] = [c for c in b.get("checks", []) if c.get("name") != "selftest"]
    return a.pop("scale_calibration")["session_id"] == b.pop("scale_calibration")["session_id"] and a == b
