"""The station's scale calibration and its history: written only from a validation that passed its
gates (with its session id and checks), every earlier one kept, shown and reverted through
``station scale-calibration show|history|revert``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from station import scale_calibration as scal
from station.cli import main
from station.record import station_lock

CHECKS = [
    {"name": "rigid_max", "passed": True, "value": 0.2, "limit": 6.0, "severity": "fail", "message": "ok"}
]


def cal(width: float, session: str) -> scal.ScaleCalibration:
    return scal.ScaleCalibration(groove_width_mm=width, u_mm=0.0004, session_id=session, checks=CHECKS)


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["scale-calibration", *args])
    out, err = capsys.readouterr()
    return code, out, err


def show(capsys: pytest.CaptureFixture[str], data: Path) -> dict[str, Any]:
    code, out, _ = cli(capsys, "show", "--data", str(data), "--json")
    doc: dict[str, Any] = json.loads(out)
    assert code == (0 if doc["calibration"] is not None else 1)
    return doc


def results(**change: Any) -> dict[str, Any]:
    base = {
        "scale_calibration": {"groove_width_mm": 0.79, "u_mm": 0.0004, "session_id": "s1"},
        "checks": CHECKS,
    }
    return {**base, **change}


def test_only_a_validation_that_succeeded_and_passed_every_gate_gives_a_calibration() -> None:
    assert scal.from_validation("validation", "succeeded", results()) is not None
    assert scal.from_validation("validation", "failed", results()) is None
    assert scal.from_validation("repeatability", "succeeded", results()) is None
    failed = [{**CHECKS[0], "passed": False}]
    assert scal.from_validation("validation", "succeeded", results(checks=failed)) is None
    assert scal.from_validation("validation", "succeeded", results(checks=None)) is None  # never checked
    warned = [*CHECKS, {**CHECKS[0], "name": "positions_measured", "severity": "warn", "passed": False}]
    kept = scal.from_validation("validation", "succeeded", results(checks=warned))
    assert kept is not None
    assert kept.checks == warned  # the file carries the checks it passed (and the warnings)


def test_write_show_history_and_revert_step_back_through_every_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = tmp_path / "data"
    data.mkdir()
    code, out, _ = cli(capsys, "show", "--data", str(data))
    assert code == 1
    assert "no scale calibration" in out
    assert "station run validation" in out
    scal.write(data, cal(0.781, "aaaa1111"))
    scal.write(data, cal(0.786, "bbbb2222"))
    doc = show(capsys, data)
    assert doc["calibration"]["version"] == 2
    assert doc["calibration"]["session_id"] == "bbbb2222"
    assert doc["calibration"]["checks"] == CHECKS
    assert doc["entry"]["action"] == "validation"
    assert doc["entry"]["previous"] == 1
    assert scal.load(scal.station_file(data)).groove_width_mm == 0.786  # what sessions measure with
    code, out, _ = cli(capsys, "history", "--data", str(data), "--json")
    assert [(e["version"], e["action"]) for e in json.loads(out)] == [(2, "validation"), (1, "validation")]

    code, out, _ = cli(capsys, "revert", "--data", str(data), "--json")
    assert code == 0
    entry = json.loads(out)
    assert (entry["version"], entry["action"], entry["restores"]) == (3, "revert", 1)
    now = show(capsys, data)["calibration"]
    assert (now["groove_width_mm"], now["session_id"], now["version"]) == (0.781, "aaaa1111", 3)

    code, out, _ = cli(capsys, "revert", "--data", str(data))  # before the first: none
    assert code == 0
    assert "no scale calibration now" in out
    assert not scal.station_file(data).exists()
    assert show(capsys, data)["calibration"] is None
    code, _, err = cli(capsys, "revert", "--data", str(data))
    assert code == 1
    assert "no earlier scale calibration" in err
    # nothing is lost: every version is still in the history
    code, out, _ = cli(capsys, "history", "--data", str(data))
    assert [line.split()[0] for line in out.splitlines()] == ["4", "3", "2", "1"]
    assert "0.786000 mm" in out


def test_a_file_from_before_the_history_is_kept_as_its_first_entry(tmp_path: Path) -> None:
    data = tmp_path / "data"
    scal.save(
        scal.ScaleCalibration(groove_width_mm=0.770, u_mm=0.0003, session_id="old00000"),
        data / scal.FILE_NAME,
    )
    scal.write(data, cal(0.790, "new11111"))
    assert [(e.version, e.action) for e in scal.history(data)] == [(1, "found"), (2, "validation")]
    back = scal.revert(data)
    assert back.calibration is not None
    assert (back.calibration.groove_width_mm, back.calibration.session_id) == (0.770, "old00000")
    with pytest.raises(scal.NothingToRevertError):
        scal.revert(data)  # what came before the found file is not known


def test_revert_is_refused_while_a_session_holds_the_station(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = tmp_path / "data"
    scal.write(data, cal(0.781, "aaaa1111"))
    scal.write(data, cal(0.786, "bbbb2222"))
    with station_lock(data, "cafe0000beef"):
        code, _, err = cli(capsys, "revert", "--data", str(data))
    assert code == 1
    assert "session cafe0000beef is running" in err
    assert scal.load(scal.station_file(data)).session_id == "bbbb2222"  # unchanged
