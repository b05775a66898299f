"""The serial port lifecycle both serial links share (drivers/_serial.py), over real pyserial ports."""

from __future__ import annotations

import os
import pty

import pytest
import serial

from drivers._serial import SerialPort
from station.devices import DeviceBusyError, DeviceConnectionError


def test_a_port_by_url_opens_carries_bytes_and_closes_twice() -> None:
    port = SerialPort("loop://")
    with pytest.raises(DeviceConnectionError, match="connect\\(\\) first"):
        port.require("the port is not open: connect() first")
    port.open(timeout_s=0.2, write_timeout_s=0.2, baudrate=57600)
    port.open(timeout_s=0.2, write_timeout_s=0.2)  # a second open does nothing
    line = port.require("not open")
    line.write(b"where\r")
    assert line.read(6) == b"where\r"
    port.close()
    port.close()
    assert not port.is_open
    with pytest.raises(DeviceConnectionError, match="not open"):
        port.require("not open")


def test_an_injected_port_is_kept_and_opens_again() -> None:
    injected = serial.serial_for_url("loop://", do_not_open=True)
    port = SerialPort(injected)
    port.open(timeout_s=0.1, write_timeout_s=0.1)
    assert port.require("x") is injected
    assert injected.timeout == 0.1
    port.close()
    assert not injected.is_open
    port.open(timeout_s=0.1, write_timeout_s=0.1)
    assert port.is_open
    assert port.require("x") is injected
    port.close()


def test_a_second_opener_of_a_real_pty_is_told_the_port_is_in_use() -> None:
    master, slave = pty.openpty()
    path = os.ttyname(slave)
    first, second = SerialPort(path), SerialPort(path)
    try:
        first.open(timeout_s=0.1, write_timeout_s=0.1)
        with pytest.raises(DeviceBusyError, match="in use by another program"):
            second.open(timeout_s=0.1, write_timeout_s=0.1)
        assert not second.is_open
    finally:
        first.close()
        os.close(slave)
        os.close(master)


def test_a_missing_port_names_itself_and_what_to_check() -> None:
    with pytest.raises(DeviceConnectionError, match=r"cannot open '/dev/does-not-exist'.*check the port"):
        SerialPort("/dev/does-not-exist").open(timeout_s=0.1, write_timeout_s=0.1)
