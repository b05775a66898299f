"""examples/http_sessions.py runs both sessions against a served station with plain HTTP."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from tests.api.conftest import TOKEN, ServeFactory

EXAMPLE = Path(__file__).parents[2] / "examples" / "http_sessions.py"
PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0]]


@pytest.mark.parametrize("manual", [False, True], ids=["sim-operator", "script-answers-prompts"])
def test_the_http_example_runs_validation_and_repeatability(
    make_served: ServeFactory, manual: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    served = make_served(manual=manual)
    spec = importlib.util.spec_from_file_location("http_sessions", EXAMPLE)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    argv = [
        "--url", served.base, "--token", TOKEN,
        "--validation", json.dumps({"pattern_um": PATTERN}),
        "--repeatability", json.dumps({"cycles": 3, "joints": [1, 2], "warmup_cycles": 0}),
    ]  # fmt: skip
    if manual:
        argv.append("--answer-prompts")
    assert module.main(argv) == 0
    out = capsys.readouterr().out
    assert "validation" in out
    assert "RP (mm): J1" in out
    sessions = served.service.record.list_sessions()
    assert sorted(s.kind for s in sessions) == ["repeatability", "validation"]
    assert all(s.state == "succeeded" for s in sessions)
