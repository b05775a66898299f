"""A local acknowledgement for tests: made by the loopback factory, as the operator page on the station
itself would (``station.local_ack``)."""

from __future__ import annotations

from station.local_ack import LocalAcknowledgement


def local_ack() -> LocalAcknowledgement:
    """A fresh acknowledgement from 127.0.0.1."""
    return LocalAcknowledgement.from_loopback("127.0.0.1")
