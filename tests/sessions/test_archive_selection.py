"""Issue 24, item 3: ``reanalyse`` and ``sweep`` read an archive selection of stored sessions, named by id
(``sessions=[...]``) or by a filter (``select={"kind", "station", "since"}``); every session is checked
before any task is sent; the sweep ranks the trials over the whole selection, with per-session figures."""

from __future__ import annotations

import shutil
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

from station.cli import main
from station.kinds import summary, table_rows
from station.kinds.sweep.report import sweep_tables
from station.kinds.sweep.results import SweepResults
from station.plans import PlanError
from station.record import Record
from station.record._schema import sessions as sessions_table
from station.session import run_session

GRID = {"skip": [1, 2], "testwidth": [3, 5]}


class Archive:
    """Three validation sessions recorded on the simulated station (8, 4 and 4 positions) and a sweep of
    the first: a small lab archive."""

    def __init__(self, data: Path) -> None:
        self.data = data
        self.validations = [_run("validation", data, {"steps_per_side": n}).id for n in (2, 1, 1)]
        self.sweep = _run("sweep", data, {"session": self.validations[0], "grid": {"skip": [1]}}).id

    def copy(self, to: Path) -> Path:
        """A copy of the archive's data directory (record and images) to change."""
        shutil.copytree(self.data, to)
        return to


def _run(kind: str, data: Path, params: dict[str, Any]) -> Any:
    outcome = run_session(kind, sim=kind == "validation", params=params, data=data)
    assert outcome.state == "succeeded", outcome.error
    return outcome


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Archive:
    return Archive(tmp_path_factory.mktemp("archive") / "data")


def _steps_and_measurements(data: Path, session_id: str) -> tuple[int, int]:
    with Record(data) as record:
        return len(record.steps(session_id)), len(record.measurements(session_id))


@pytest.mark.timeout(240)
def test_a_sweep_ranks_its_trials_over_every_session_of_a_selection(archive: Archive, tmp_path: Path) -> None:
    out = _run("sweep", archive.data, {"sessions": archive.validations, "grid": GRID})
    results = out.results
    assert results["sessions"] == archive.validations
    assert results["source_session"] is None
    trials = results["trials"]
    assert [t["overrides"] for t in trials] == [
        {"skip": 1, "testwidth": 3},
        {"skip": 1, "testwidth": 5},
        {"skip": 2, "testwidth": 3},
        {"skip": 2, "testwidth": 5},
    ]
    # each trial's figures over the selection, by hand from its per-session figures: MeanE over every
    # position (each session's mean weighted by its positions), MaxE the largest of any session
    for t in trials:
        per = t["sessions"]
        assert [s["session"] for s in per] == archive.validations
        assert [s["positions"] for s in per] == [8, 4, 4]
        assert t["positions"] == 16
        for fit in ("", "parallelogram_"):
            hand_mean = sum(s["positions"] * s[f"{fit}mean_um"] for s in per) / 16
            assert t[f"{fit}mean_um"] == pytest.approx(hand_mean, rel=1e-12)
            assert t[f"{fit}max_um"] == max(s[f"{fit}max_um"] for s in per)
    # the ranking: lowest MeanE (to 1e-4 um), then lowest MaxE, after the parallelogram fit (Table 1's)
    by_hand = min(
        trials,
        key=lambda t: (
            round(sum(s["positions"] * s["parallelogram_mean_um"] for s in t["sessions"]) / 16, 4),
            max(s["parallelogram_max_um"] for s in t["sessions"]),
        ),
    )
    assert results["best"] == by_hand["number"]

    # the CSV: per trial, its figures over the selection, then each session's
    rows = table_rows("sweep", results)
    assert len(rows) == 4 * (1 + 3)
    assert [r["session"] for r in rows[:4]] == ["all", *archive.validations]
    assert rows[0]["parallelogram_mean_um"] == trials[0]["parallelogram_mean_um"]
    assert rows[2]["parallelogram_mean_um"] == trials[0]["sessions"][1]["parallelogram_mean_um"]
    assert rows[2]["overrides.testwidth"] == 3

    # a session's figures in the selection are that session's own sweep's
    alone = _run("sweep", archive.data, {"session": archive.validations[1], "grid": GRID}).results
    for t, own in zip(trials, alone["trials"], strict=True):
        mine = t["sessions"][1]
        for key in ("mean_um", "max_um", "parallelogram_mean_um", "parallelogram_max_um", "error"):
            assert mine[key] == own[key]

    # the report: Table 1 over the selection, and the per-session table (MeanE / MaxE of every trial)
    tables = sweep_tables(SweepResults.model_validate(results), "paper")
    assert "images of 3 validation sessions" in tables["sweep"].text()
    per_session = tables["sweep_sessions"]
    assert [row[0] for row in per_session.rows] == archive.validations
    assert per_session.headers[2] == f"trial {results['best']} (best)"
    best = next(t for t in trials if t["number"] == results["best"])
    first = best["sessions"][0]
    assert (
        per_session.rows[0][2]
        == f"{first['parallelogram_mean_um']:.3f} / {first['parallelogram_max_um']:.3f}"
    )


@pytest.mark.timeout(240)
def test_a_selection_by_filter_takes_the_kind_station_and_days_asked(
    archive: Archive, tmp_path: Path
) -> None:
    data = archive.copy(tmp_path / "data")
    old, other, kept = archive.validations
    with Record(data) as record, record.engine.begin() as conn:
        # one validation of last year, one of another station's: the filter leaves both out
        conn.execute(
            sa.update(sessions_table)
            .where(sessions_table.c.id == old)
            .values(created_at=datetime(2025, 6, 1, tzinfo=UTC))
        )
        conn.execute(
            sa.update(sessions_table).where(sessions_table.c.id == other).values(station="a465-lab-2")
        )
    select = {"kind": "validation", "station": "sim", "since": "2026-01-01"}
    sweep = _run("sweep", data, {"select": select, "grid": {"skip": [1]}})
    assert sweep.results["sessions"] == [kept]
    with Record(data) as record:
        assert record.get_session(sweep.id).params["plan"]["select"] == select

    # a re-analysis of every validation of the lab's station, whatever the day: each source measured
    # again gives its own stored results, bit for bit
    again = _run("reanalyse", data, {"select": {"kind": "validation", "station": "sim"}})
    sources = again.results["sessions"]
    assert [s["source_session"] for s in sources] == [old, kept]  # oldest first
    with Record(data) as record:
        for s in sources:
            stored = record.get_session(s["source_session"]).results
            assert stored is not None
            redone, original = dict(s["validation"]), dict(stored)
            assert redone.pop("scale_calibration") == original.pop("scale_calibration")
            # the controller's self-test is the live session's (station.selftest_status), not its images'
            original.pop("selftest", None)
            original["checks"] = [c for c in original["checks"] if c["name"] != "selftest"]
            assert redone == original
        assert len(record.measurements(again.id)) == 8 + 4
    # the terminal's summary: each source's, under its session
    text = summary("reanalyse", again.results)
    assert text.index(f"session {old}:") < text.index(f"session {kept}:")
    assert text.count("raw (rigid) error mean") == 2


@pytest.mark.timeout(240)
def test_a_bad_selection_is_refused_whole_before_any_work(
    archive: Archive, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = archive.copy(tmp_path / "data")
    good, damaged, _ = archive.validations
    with Record(data) as record:
        lost = record.captures(damaged)[2].path
    (data / lost).unlink()
    wanted = [good, "fffff0000fff", archive.sweep, damaged]
    code = main(["run", "sweep", "--data", str(data), "--param", f"sessions={wanted}".replace("'", '"')])
    assert code != 0
    err = capsys.readouterr().err
    assert "3 of the 4 selected sessions cannot be read; nothing was measured" in err
    assert "'fffff0000fff'" in err
    assert "station sessions" in err
    assert f"session {archive.sweep} (sweep): it is a sweep session; a sweep needs validation" in err
    assert f"session {damaged} (validation): 1 of its 4 images are missing" in err
    assert lost in err
    assert "station sessions import" in err
    assert good not in err.split("nothing was measured")[1]  # the good one is not blamed
    with Record(data) as record:
        refused = record.list_sessions("sweep")[0]  # the newest
        assert refused.state == "failed"
        assert refused.params["plan"]["sessions"] == wanted
        assert _steps_and_measurements(data, refused.id) == (0, 0)  # no trial ran

    # the same for a re-analysis: nothing measured, every bad session named
    out = run_session("reanalyse", params={"sessions": [damaged, archive.sweep]}, data=data)
    assert out.state == "failed"
    assert out.error is not None
    assert "2 of the 2 selected sessions" in out.error
    assert "captures nothing to measure again" in out.error
    assert _steps_and_measurements(data, out.id) == (0, 0)


@pytest.mark.parametrize(
    ("params", "says"),
    [
        ({}, "give exactly one of session, sessions or select (got none of them)"),
        ({"session": "abcd1234", "sessions": ["abcd1234"]}, "(got session and sessions)"),
        ({"sessions": []}, "sessions is empty"),
        ({"sessions": ["abcd1234", "ABCD1234"]}, "names 'ABCD1234' twice"),
        ({"select": {"kind": "validation", "day": "2026-01-01"}}, "select.day"),
        ({"select": {"since": "last year"}}, "select.since"),
    ],
)
def test_selection_parameters_are_checked_when_the_session_is_asked_for(
    tmp_path: Path, params: dict[str, Any], says: str
) -> None:
    for kind in ("sweep", "reanalyse"):
        with pytest.raises(PlanError, match="parameters") as caught:
            run_session(kind, params=params, data=tmp_path / "data")
        assert says in str(caught.value)
    with Record(tmp_path / "data") as record:
        assert record.list_sessions() == []  # no session was made
