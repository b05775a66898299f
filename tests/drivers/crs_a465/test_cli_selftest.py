"""``station robot selftest`` (issue 23, item 3): the result object printed (``--json``), the exit code,
the stop left latched by the halt check, and its refusals before anything is opened."""

from __future__ import annotations

import json

import pytest

from station.cli import main

pytestmark = pytest.mark.timeout(120)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["robot", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_the_halt_check_on_a_simulated_station_prints_its_result(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "--sim", "--json", "selftest", "--checks", "halt")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["passed"] is True
    assert doc["latched"] is True  # the halt leaves the stop for a person to acknowledge
    (halt,) = doc["checks"]
    assert halt["name"] == "halt"
    assert halt["state"] == "passed"
    assert halt["details"]["stopping_angle_deg"] <= halt["details"]["stated_stop_angle_deg"]
    assert 0.5 < halt["details"]["travelled_deg"] < 9.5
    assert doc["identity"]["model"] == "A465"
    assert set(doc) == {
        "passed",
        "checks",
        "identity",
        "latched",
        "start_joints_deg",
        "started_at",
        "finished_at",
    }


def test_refusals_before_anything_is_opened(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "--port", "/dev/null-robot", "selftest")
    assert code == 2
    assert "selftest needs --config FILE" in err
    code, _, err = run(capsys, "--sim", "selftest", "--checks", "world,bogus")
    assert code == 2
    assert "--checks: unknown ['bogus']" in err
    assert "directions,world,ready,halt" in err
