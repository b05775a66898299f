"""Issue 18, item 8 (table row 16): ``station run --json`` prints its outcome object as the last line on
stdout whatever failed (state ``failed`` and the error), the record's failure included."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from station.cli import main
from station.record import Record, RecordError
from station.runner import FINAL_STATES, SessionState

SECRET = "hunter2-Zq9"


def _last(capsys: pytest.CaptureFixture[str]) -> tuple[dict[str, Any], str]:
    out, err = capsys.readouterr()
    assert out.strip(), f"nothing on stdout; stderr: {err[-2000:]}"
    doc: dict[str, Any] = json.loads(out.strip().splitlines()[-1])
    return doc, err


def test_a_record_that_cannot_be_opened_still_gives_the_outcome_object(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    url = f"postgresql+psycopg://station:{SECRET}@/postgres?host={tmp_path}/no-server&connect_timeout=2"
    code = main(["run", "repeatability", "--sim", "--json", "--data", str(tmp_path), "--database", url])
    doc, err = _last(capsys)
    assert code == 1
    assert doc["state"] == "failed"
    assert doc["id"] is None  # no session could be made
    assert doc["kind"] == "repeatability"
    assert doc["results"] == {}
    assert "cannot open the record" in doc["error"]
    assert SECRET not in doc["error"] + err
    assert "Traceback" not in err


def test_a_record_failing_at_the_end_of_a_session_still_gives_the_outcome_object(
    recorded: tuple[Path, str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The session ran; recording its final state fails (a full disk, a lost server: injected at the
    record's ``set_state``): the outcome says ``failed`` with that error and the session's id."""
    import shutil

    data = tmp_path / "data"
    shutil.copytree(recorded[0], data)
    real = Record.set_state

    def failing(self: Record, session_id: str, state: str, *, error: str | None = None) -> None:
        if state in FINAL_STATES:
            raise RecordError(
                f"cannot write to the record at {self.url}: database or disk is full (injected)"
            )
        real(self, session_id, state, error=error)

    monkeypatch.setattr(Record, "set_state", failing)
    code = main(["run", "reanalyse", "--param", f"session={recorded[1]}", "--json", "--data", str(data)])
    doc, err = _last(capsys)
    assert code == 1
    assert doc["state"] == "failed"
    assert doc["kind"] == "reanalyse"
    assert doc["id"] is not None
    assert doc["id"] != recorded[1]
    assert "database or disk is full" in doc["error"]
    assert set(doc) == {"id", "kind", "state", "results", "error"}
    monkeypatch.undo()
    with Record(data) as rec:
        assert rec.get_session(doc["id"]).state == SessionState.RUNNING  # the record could not say more
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("args", "code"),
    [
        (["run", "repeatability", "--sim", "--param", "cycles=-1"], 2),
        (["run", "reanalyse", "--param", "session=abcdef012345"], 1),
        (["run", "repeatability", "--sim", "--jobs", "0"], 2),
    ],
)
def test_usage_and_lookup_failures_give_the_outcome_object_too(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], code: int
) -> None:
    try:
        got = main([*args, "--json", "--data", str(tmp_path / "data")])
    except SystemExit as exc:  # argparse's own usage errors
        got = int(exc.code or 0)
    doc, _ = _last(capsys)
    assert got == code
    assert doc["state"] == "failed"
    assert doc["error"]
