"""The devices' typed errors: each says what the operator should check or do."""

from __future__ import annotations


class DeviceError(RuntimeError):
    """Base class of every device failure."""


class DeviceConnectionError(DeviceError):
    """The device cannot be reached, or the link was lost. Reconnect, then re-read its state."""


class DeviceTimeoutError(DeviceError):
    """The device did not answer in time."""


class DeviceProtocolError(DeviceError):
    """The device answered something that cannot be parsed (garbled line, unexpected reply)."""


class MotionRejectedError(DeviceError):
    """A motion failed validation on the host (limits, step, keep-out); nothing was sent."""


class NotSupportedError(DeviceError):
    """The device has no such ability (e.g. gain on a frame grabber)."""


class ControllerError(DeviceError):
    """The controller refused or failed a command; ``controller_text`` is what it printed.

    Drivers raise subclasses for the errors they recognise (arm power off, joint limit, not homed ...);
    the message says what the operator should do.
    """

    def __init__(self, message: str, *, controller_text: str = "", code: int | None = None) -> None:
        super().__init__(message)
        self.controller_text = controller_text
        self.code = code


class MotionStoppedError(DeviceError):
    """A motion was stopped (``stop()``, or a halt at the controller) before reaching its target.

    ``stop()`` latches: every motion raises this until the stop is acknowledged at the station
    (``acknowledge_stop``). Re-read the position before going on.
    """


class StopLatchedError(MotionStoppedError):
    """A stop is latched: motions are refused until a person at the station acknowledges it
    (``acknowledge_stop`` with a ``station.local_ack.LocalAcknowledgement``); ``reason`` says what
    latched it."""

    def __init__(self, message: str, *, reason: str = "") -> None:
        super().__init__(message)
        self.reason = reason


__all__ = [
    "ControllerError",
    "DeviceConnectionError",
    "DeviceError",
    "DeviceProtocolError",
    "DeviceTimeoutError",
    "MotionRejectedError",
    "MotionStoppedError",
    "NotSupportedError",
    "StopLatchedError",
]
