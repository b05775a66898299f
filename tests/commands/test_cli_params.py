"""``station run KIND --param NAME=VALUE``: VALUE is JSON unless the plan's parameter is a string, which
takes the text as typed (a session id of hex digits such as ``505e3210`` is a number to JSON)."""

from __future__ import annotations

import argparse

import pytest

from station.commands.run import parse_params, text_params


@pytest.mark.parametrize("session", ["505e3210", "12345678", "1e5f0000", "abcd1234"])
def test_a_session_id_stays_the_text_typed(session: str) -> None:
    parser = argparse.ArgumentParser()
    got = parse_params(parser, [f"session={session}", "seed=3"], text_params("reanalyse"))
    assert got == {"session": session, "seed": 3}


def test_other_values_are_json_and_unknown_kinds_have_no_string_parameters() -> None:
    parser = argparse.ArgumentParser()
    assert "session" in text_params("reanalyse")
    assert text_params(None) == text_params("no-such-kind") == frozenset()
    got = parse_params(parser, ["cycles=10", "joints=[1, 2]", "name=plain"], text_params("repeatability"))
    assert got == {"cycles": 10, "joints": [1, 2], "name": "plain"}
