"""``station zsensor``: the CLI contract against a fresh twin and a missing port."""

from __future__ import annotations

import json

import pytest

from station.cli import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["zsensor", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_sim_read_prints_one_json_object_per_reading(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--sim", "--json", "read", "--count", "3")
    assert code == 0
    lines = [json.loads(line) for line in out.splitlines()]
    assert len(lines) == 3
    assert all(d["ok"] for d in lines)
    # the default twin's world has the camera in focus: the head reads about the working distance (the
    # true arm's camera may tilt a little from the level artifact, 30 mm beside the optical axis)
    assert all(d["z_mm"] == pytest.approx(68.0, abs=0.5) for d in lines)


def test_sim_status(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--sim", "--json", "status")
    assert code == 0
    assert json.loads(out)["state"] == "ok"


def test_a_missing_port_exits_1_with_the_reason(capsys: pytest.CaptureFixture[str], tmp_path) -> None:
    code, out, err = run(capsys, "--port", str(tmp_path / "ttyUSB9"), "read")
    assert (code, out) == (1, "")
    assert "cannot open" in err


@pytest.mark.parametrize("argv", [("--sim", "--baud", "1234", "read"), ("--sim", "--timeout", "0", "read")])
def test_bad_option_values_exit_2(capsys: pytest.CaptureFixture[str], argv: tuple[str, ...]) -> None:
    code, _, err = run(capsys, *argv)
    assert code == 2
    assert "bad option" in err


def test_a_bad_count_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["zsensor", "--sim", "read", "--count", "0"])
    assert info.value.code == 2
    assert "--count must be 1 to 100000" in capsys.readouterr().err
