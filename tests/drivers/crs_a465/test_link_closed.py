"""A port closed by another thread while the link uses it is a DeviceConnectionError, not a pyserial
TypeError (the runner's abort once met ``'NoneType' object cannot be interpreted as an integer``)."""

from __future__ import annotations

import os
import pty

import pytest

from drivers.crs_a465._link import SerialTransport
from station.devices import DeviceConnectionError


def test_writing_and_reading_on_a_port_closed_under_the_link_say_so() -> None:
    master, slave = pty.openpty()
    try:
        link = SerialTransport(os.ttyname(slave))
        link.open()
        port = link._port()
        port.fd = None  # what pyserial's close() leaves while another thread is mid-call
        with pytest.raises(DeviceConnectionError, match="closed while in use"):
            link.write_bytes(b"\x1a")
        with pytest.raises(DeviceConnectionError, match="closed while in use"):
            link.write_line("w0")
        port.fd = os.open(os.ttyname(slave), os.O_RDWR | os.O_NOCTTY)  # let close() work
        link.close()
    finally:
        os.close(master)
        os.close(slave)
