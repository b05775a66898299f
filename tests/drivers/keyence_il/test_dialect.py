"""The DL-RS1A dialect module alone: framing, replies, error replies and special readouts."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from drivers.keyence_il._dialect import ErrorReplyError, encode, parse_readout, parse_reply
from station.devices import DeviceProtocolError


def test_command_framing() -> None:
    assert encode("M0") == b"M0\r\n"


def test_reply_fields_after_the_echo() -> None:
    assert parse_reply("M0", "M0,+01.234,-00.500") == ["+01.234", "-00.500"]


@pytest.mark.parametrize(
    ("line", "code", "words"),
    [("ER,M0,00", "00", "invalid command"), ("ER,M0,65", "65", "ID number"), ("ER,M0,42", "42", "unknown")],
)
def test_error_replies(line: str, code: str, words: str) -> None:
    with pytest.raises(ErrorReplyError, match=words) as info:
        parse_reply("M0", line)
    assert info.value.code == code


@pytest.mark.parametrize("line", ["", "M0", "MS,+01.000", "ER,M0", "ER,SR,00", "M0+01.000", "\ufffd\ufffd"])
def test_anything_else_is_a_protocol_error(line: str) -> None:
    with pytest.raises(DeviceProtocolError):
        parse_reply("M0", line)


@pytest.mark.parametrize(
    ("text", "kind", "value"),
    [
        ("+01.234", "value", 1.234),
        ("-10.000", "value", -10.0),
        ("+EE.EEE", "error", None),
        ("+99.999", "above", None),
        ("-99.999", "below", None),
        ("-FF.FFF", "invalid", None),
    ],
)
def test_readouts(text: str, kind: str, value: float | None) -> None:
    r = parse_readout(text)
    assert (r.kind, r.value_mm) == (kind, value)


@pytest.mark.parametrize("text", ["1.234", "+1.234", "+01.23", "+001.234", "+0a.234", "nan", ""])
def test_unreadable_values(text: str) -> None:
    with pytest.raises(DeviceProtocolError, match="unreadable"):
        parse_readout(text)


@given(st.text(max_size=40))
def test_any_reply_line_parses_or_is_a_protocol_error(line: str) -> None:
    """Whatever arrives, the dialect either reads it or raises DeviceProtocolError: never another
    exception, and never a distance from a line that is not ``M0,±**.***``."""
    try:
        fields = parse_reply("M0", line)
    except DeviceProtocolError:
        return
    assert line.startswith("M0,")
    for field in fields:
        try:
            r = parse_readout(field)
        except DeviceProtocolError:
            continue
        if r.kind == "value":
            assert r.value_mm is not None
            assert abs(r.value_mm) < 100
