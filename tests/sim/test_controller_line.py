"""The twin's optional serial-line pacing (``line_baud``): replies leave at the line's byte rate."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from sim.controller import TwinSettings, start_twin
from tests.sim.test_controller import Terminal


def test_line_pacing_is_off_by_default_and_must_be_positive():
    assert TwinSettings().line_baud is None
    with pytest.raises(ValidationError):
        TwinSettings(line_baud=0)


def test_a_paced_twin_holds_a_reply_for_its_bytes_at_the_line_rate():
    # 1200 baud: 120 bytes a second; "Current Speed: 50% of max.\r\n" (28 bytes) takes about 0.23 s
    with start_twin(time_scale=100.0, line_baud=1200) as twin:
        term = Terminal(twin.port)
        try:
            term.type(b"speed\r")
            assert term.until(b"speed\r\n") == b"speed\r\n"
            assert term.nothing_for(0.1)  # the reply is still on the (simulated) line
            assert term.until(b"$ ") == b"Current Speed: 50% of max.\r\n$ "
        finally:
            term.close()
