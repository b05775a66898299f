"""The station's device interfaces: what plans and the runner may ask of hardware.

Each interface is a small typed ``Protocol``; a real driver (``drivers/``) and its simulated twin
(``sim/``) are siblings that both satisfy it, and one parametrised contract suite runs against every
implementation. Units are mm and degrees at every interface (the X-Y table too: its operator prompt
shows inches). Errors are the exceptions below, each with a message that tells the operator what to do.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

# --------------------------------------------------------------------------- errors


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
    """A motion was stopped (``stop()``) before reaching its target; re-read the position before going on."""


# --------------------------------------------------------------------------- robot

JOINT_COUNT = 6


@dataclass(frozen=True)
class RobotStatus:
    """What the controller reports; a field it cannot report is ``None`` (unknown), never a guess.

    ``speed_pct`` is the speed override (percent of maximum); ``last_error`` the last controller error
    text this connection saw (``None`` when there was none).
    """

    power: bool | None
    homed: bool | None
    moving: bool | None
    speed_pct: float | None
    last_error: str | None = None


@dataclass(frozen=True)
class RobotPosition:
    """Joint angles (deg) attained and commanded, and the controller's WORLD row.

    ``joints_deg`` is the attained (encoder) position, ``commanded_joints_deg`` the set-point.
    ``world_mm_deg`` is ``(x, y, z, z_rot, y_rot, x_rot)`` as the controller prints it for the attained
    position (mm, deg), or ``None`` where the controller does not report it.
    """

    joints_deg: tuple[float, ...]
    commanded_joints_deg: tuple[float, ...]
    world_mm_deg: tuple[float, ...] | None = None


@runtime_checkable
class Robot(Protocol):
    """A six-joint arm moved in joint space (degrees).

    Every motion is checked on the host (joint limits, maximum step, keep-out) before anything is
    sent: a rejected motion raises ``MotionRejectedError`` and leaves the arm untouched. Motions
    return when the controller has accepted them; ``wait_settled`` blocks until the arm is still.
    Controller refusals raise ``ControllerError`` subclasses; a lost link ``DeviceConnectionError``
    (``connect()`` again re-reads the arm state).
    """

    def connect(self) -> None:
        """Open the link and read the arm's state."""

    def close(self) -> None:
        """Release the link; safe to call twice."""

    def status(self) -> RobotStatus:
        """Power, homing, motion and speed as the controller reports them."""

    def where(self) -> RobotPosition:
        """Attained and commanded joint angles (and the WORLD row where known)."""

    def move_joint(self, axis: int, delta_deg: float) -> None:
        """Move one joint (1-6) by ``delta_deg`` relative to where it is commanded now."""

    def move_joints(self, target_deg: Sequence[float]) -> None:
        """Move to six absolute joint angles (deg)."""

    def home(self) -> None:
        """Home the arm."""

    def ready(self) -> None:
        """Go to the controller's ready pose."""

    def set_speed(self, percent: float) -> None:
        """Set the speed override, in percent of maximum."""

    def stop(self) -> None:
        """Stop any motion now (callable from another thread while a motion is in progress)."""

    def wait_settled(self, timeout_s: float | None = None) -> None:
        """Block until the arm has stopped moving (raise DeviceTimeoutError after ``timeout_s``)."""


# --------------------------------------------------------------------------- camera

ImageArray = npt.NDArray[np.uint8] | npt.NDArray[np.uint16]


@dataclass(frozen=True)
class Frame:
    """One image from a camera. ``image`` is 2-D uint8 or uint16; ``frame_id`` never repeats."""

    image: ImageArray
    timestamp_s: float
    frame_id: int
    averaged: int = 1


@dataclass(frozen=True)
class CameraStatus:
    connected: bool
    model: str
    width: int
    height: int
    pixel_format: str
    exposure_us: float | None = None
    gain_db: float | None = None
    frame_rate_hz: float | None = None
    extra: dict[str, str] = field(default_factory=dict)


@runtime_checkable
class Camera(Protocol):
    """A monochrome camera or frame grabber."""

    def open(self) -> None:
        """Open the device and prepare to stream."""

    def close(self) -> None:
        """Stop streaming and release the device; safe to call twice."""

    def grab(self, timeout_s: float = 2.0) -> Frame:
        """Return the next new frame (never a reused one); raise DeviceTimeoutError when none comes."""

    def grab_many(self, count: int, *, average: bool = False, timeout_s: float = 2.0) -> list[Frame]:
        """Return ``count`` new frames, or one frame averaged over ``count`` when ``average``."""

    def status(self) -> CameraStatus:
        """Size, format and settings as the device reports them."""


# --------------------------------------------------------------------------- X-Y table


@dataclass(frozen=True)
class TablePosition:
    """A table position in mm, table axes."""

    x_mm: float
    y_mm: float


@runtime_checkable
class XYTable(Protocol):
    """An X-Y positioning table in mm (the manual Vernier table asks an operator to turn it)."""

    def position(self) -> TablePosition:
        """The last confirmed position."""

    def move_to(self, x_mm: float, y_mm: float, *, timeout_s: float | None = None) -> TablePosition:
        """Move to an absolute position and return the position actually set (as confirmed)."""


__all__ = [
    "JOINT_COUNT",
    "Camera",
    "CameraStatus",
    "ControllerError",
    "DeviceConnectionError",
    "DeviceError",
    "DeviceProtocolError",
    "DeviceTimeoutError",
    "Frame",
    "ImageArray",
    "MotionRejectedError",
    "MotionStoppedError",
    "NotSupportedError",
    "Robot",
    "RobotPosition",
    "RobotStatus",
    "TablePosition",
    "XYTable",
]
