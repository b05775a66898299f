"""The station's device interfaces: what plans and the runner may ask of hardware.

Each interface is a small typed ``Protocol``; a real driver (``drivers/``) and its simulated twin
(``sim/``) are siblings that both satisfy it, and one parametrised contract suite runs against every
implementation. Units are mm and degrees at every interface (the X-Y table too: its operator prompt
shows inches). Errors are the exceptions below, each with a message that tells the operator what to do.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from station.local_ack import LocalAcknowledgement

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


# --------------------------------------------------------------------------- lifecycle and identity


@runtime_checkable
class Connectable(Protocol):
    """Every device's lifecycle: a factory builds it unconnected; ``connect`` opens it, ``close`` releases it.

    ``connect`` on a connected device does nothing; ``close`` is safe to call twice. The session runner
    connects all devices and closes them in reverse order in one place.
    """

    def connect(self) -> None:
        """Open the link (port, stream, prompt channel) and read the device's state."""

    def close(self) -> None:
        """Release the device; safe to call twice."""


@dataclass(frozen=True)
class DeviceIdentity:
    """Who a device is, recorded with every session: each field ``None`` where the device cannot say.

    ``model`` (e.g. the arm type from armstat, the camera's model name), ``serial`` (serial number or
    device id), ``port`` (serial port, video node, camera address), ``firmware`` (version text).
    """

    model: str | None = None
    serial: str | None = None
    port: str | None = None
    firmware: str | None = None


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
    calibrated: bool | None = None
    arm_type: str | None = None


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
    sent: a rejected motion raises ``MotionRejectedError`` and leaves the arm untouched; ``check_move``
    runs the same checks without any I/O. Motions return when the arm has arrived; ``wait_settled``
    blocks until an arm moved by someone else is still. Controller refusals raise ``ControllerError``
    subclasses; a lost link ``DeviceConnectionError`` (``connect()`` again re-reads the arm state).
    ``stop()``, a halt, an E-stop or a controller error during a motion latch: until a person at the
    station acknowledges it (``acknowledge_stop``), every motion raises ``StopLatchedError``.
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

    def check_move(self, target_deg: Sequence[float], *, start_deg: Sequence[float] | None = None) -> None:
        """Raise what ``move_joints(target_deg)`` from ``start_deg`` would raise on the host, with no I/O.

        ``start_deg`` ``None``: the last commanded position. Limits, step and keep-out only: a chain of
        moves can be checked before the first is sent.
        """

    def stop(self) -> None:
        """Stop any motion now, best effort (callable from another thread); latches until ``clear_stop``."""

    def clear_stop(self) -> None:
        """Release nothing: raise ``StopLatchedError`` when a stop is latched (what to do in its message),
        do nothing otherwise. A session's start calls it, so that no session clears a latch itself."""

    def acknowledge_stop(self, ack: LocalAcknowledgement) -> str | None:
        """Release the latch with a person's acknowledgement at the station; return what had latched it.

        Anything but a fresh, unused ``LocalAcknowledgement`` raises
        ``station.local_ack.RemoteAcknowledgementError`` and releases nothing.
        """

    def check_speed(self, percent: float) -> None:
        """Raise what ``set_speed(percent)`` would raise on the host (the speed cap), with no I/O."""

    def identity(self) -> DeviceIdentity:
        """Model, serial, port and firmware as far as the device reports them."""

    def wait_settled(self, timeout_s: float | None = None) -> None:
        """Block until the arm has stopped moving (raise DeviceTimeoutError after ``timeout_s``)."""


# --------------------------------------------------------------------------- camera

ImageArray = npt.NDArray[np.uint8] | npt.NDArray[np.uint16]

PIXEL_FORMATS = ("Mono8", "Mono16")
"""The pixel formats a station camera delivers: 2-D ``uint8`` or ``uint16`` images."""


class FrameError(DeviceProtocolError):
    """The camera delivered a frame that cannot be used (incomplete, wrong size or format).

    ``expected_bytes`` and ``got_bytes`` are set when the size was wrong.
    """

    def __init__(
        self, message: str, *, expected_bytes: int | None = None, got_bytes: int | None = None
    ) -> None:
        super().__init__(message)
        self.expected_bytes = expected_bytes
        self.got_bytes = got_bytes


class DeviceBusyError(DeviceConnectionError):
    """The device exists but another program holds it; close that program (or wait), then retry."""


class InvalidSettingError(DeviceError, ValueError):
    """A setting outside what the device accepts (the message gives its range); nothing was changed."""


@dataclass(frozen=True)
class Frame:
    """One image from a camera.

    ``image`` is 2-D uint8 or uint16 (rows, columns). ``timestamp_s`` is host time (epoch seconds) when
    the frame arrived. ``frame_id`` counts frames delivered by this camera object and never repeats;
    ``device_frame_id`` is the device's own counter where it has one (it may wrap or restart).
    ``averaged`` is how many frames were averaged into this one.
    """

    image: ImageArray
    timestamp_s: float
    frame_id: int
    averaged: int = 1
    device_frame_id: int | None = None


@dataclass(frozen=True)
class Roi:
    """A region of interest on the sensor, in pixels: offset (x right, y down) and size."""

    x: int
    y: int
    width: int
    height: int


@dataclass(frozen=True)
class CameraStatus:
    """What the camera reports; a setting it does not have is ``None``."""

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
    """A monochrome camera or frame grabber.

    ``grab`` returns a frame that arrived after the call (stale buffered frames are dropped), never the
    same frame twice; a timeout raises ``DeviceTimeoutError``, a corrupt or short frame ``FrameError``,
    a grab on a closed camera ``DeviceConnectionError``. Settings a device has are offered through the
    small protocols below (``ExposureAdjustable`` ...); check with ``isinstance``.
    """

    def connect(self) -> None:
        """Open the device and start streaming; a second call does nothing."""

    def close(self) -> None:
        """Stop streaming and release the device; safe to call twice."""

    def grab(self, timeout_s: float = 2.0) -> Frame:
        """Return the next new frame (never a reused one); raise DeviceTimeoutError when none comes."""

    def grab_many(self, count: int, *, average: bool = False, timeout_s: float = 2.0) -> list[Frame]:
        """Return ``count`` new frames, or one frame averaged over ``count`` when ``average``."""

    def status(self) -> CameraStatus:
        """Size, format and settings as the device reports them."""

    def identity(self) -> DeviceIdentity:
        """Model, serial or device id, address, firmware where the device reports them."""


@runtime_checkable
class ExposureAdjustable(Protocol):
    """A camera whose exposure time can be set (microseconds)."""

    def exposure_us(self) -> float:
        """The exposure time now, in µs."""

    def set_exposure_us(self, exposure_us: float) -> float:
        """Set the exposure time; return the value the device took (it may round)."""


@runtime_checkable
class GainAdjustable(Protocol):
    """A camera whose analogue gain can be set (dB, or the device's own unit where it has no dB)."""

    def gain_db(self) -> float:
        """The gain now."""

    def set_gain_db(self, gain_db: float) -> float:
        """Set the gain; return the value the device took."""


@runtime_checkable
class RoiSelectable(Protocol):
    """A camera that can read out a region of the sensor."""

    def roi(self) -> Roi:
        """The region read out now."""

    def set_roi(self, roi: Roi | None) -> Roi:
        """Read out ``roi`` (``None``: the whole sensor); return the region the device took."""


@runtime_checkable
class FrameRateAdjustable(Protocol):
    """A camera whose free-running frame rate can be set (Hz)."""

    def frame_rate_hz(self) -> float:
        """The frame rate now."""

    def set_frame_rate_hz(self, frame_rate_hz: float) -> float:
        """Set the frame rate; return the value the device took."""


def average_frames(frames: Sequence[Frame]) -> Frame:
    """One frame whose pixels are the mean of ``frames``, rounded to the frames' own dtype.

    All frames must have the same shape and dtype. The result keeps the last frame's ids (so ids still
    never repeat among returned frames), the mean timestamp, and ``averaged`` = the total count.
    """
    if not frames:
        raise ValueError("average_frames: no frames given; pass at least one")
    first = frames[0].image
    for f in frames[1:]:
        if f.image.shape != first.shape or f.image.dtype != first.dtype:
            raise ValueError(
                f"average_frames: frame {f.frame_id} is {f.image.shape} {f.image.dtype}, "
                f"frame {frames[0].frame_id} is {first.shape} {first.dtype}; average frames of one size only"
            )
    total = np.zeros(first.shape, dtype=np.float64)
    for f in frames:
        total += f.image
    mean = np.rint(total / len(frames))
    image: ImageArray = mean.astype(np.uint16) if first.dtype == np.uint16 else mean.astype(np.uint8)
    return Frame(
        image=image,
        timestamp_s=float(np.mean([f.timestamp_s for f in frames])),
        frame_id=frames[-1].frame_id,
        averaged=sum(f.averaged for f in frames),
        device_frame_id=frames[-1].device_frame_id,
    )


def grab_frames(
    grab: Callable[[float], Frame], count: int, *, average: bool = False, timeout_s: float = 2.0
) -> list[Frame]:
    """``Camera.grab_many`` written once over a camera's ``grab``: ``count`` frames, or their average.

    ``timeout_s`` applies to each frame.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"count must be a whole number of frames >= 1, got {count!r}")
    frames = [grab(timeout_s) for _ in range(count)]
    return [average_frames(frames)] if average else frames


# --------------------------------------------------------------------------- X-Y table


class OperatorCancelledError(DeviceError):
    """The operator cancelled a manual step; nothing was confirmed. Check the device before going on."""


@dataclass(frozen=True)
class TablePosition:
    """A table position in mm, table axes."""

    x_mm: float
    y_mm: float


@runtime_checkable
class XYTable(Protocol):
    """An X-Y positioning table in mm (the manual Vernier table asks an operator to turn it).

    ``move_to`` blocks only the calling thread until the move is done (for the manual table: until the
    operator confirms through ``station.prompts``). A target outside the travel raises
    ``MotionRejectedError`` before anything happens; a cancelled move ``OperatorCancelledError``; no
    answer within ``timeout_s`` ``DeviceTimeoutError``.
    """

    def connect(self) -> None:
        """Make the table ready (for the manual table: nothing to open; it checks its prompt channel)."""

    def close(self) -> None:
        """Release the table (withdraw any open prompt of its own); safe to call twice."""

    def identity(self) -> DeviceIdentity:
        """What the table is (model, travel), as configured."""

    def check_target(self, x_mm: float, y_mm: float) -> None:
        """Raise what ``move_to(x_mm, y_mm)`` would raise before acting (travel, non-finite values).

        No side effects: nothing is asked, nothing moves. Pre-flight checks a whole pattern with it.
        """

    def position(self) -> TablePosition:
        """The last confirmed position (DeviceError if none was confirmed yet)."""

    def move_to(self, x_mm: float, y_mm: float, *, timeout_s: float | None = None) -> TablePosition:
        """Move to an absolute position and return the position actually set (as confirmed)."""


# --------------------------------------------------------------------------- distance sensor


class OutOfRangeError(DeviceError):
    """The distance sensor has no valid distance: the target is outside its measuring range, the beam
    misses it, or too little light comes back (steep incidence, dark or shiny surface).

    Nothing is wrong with the link: move the sensor so that a surface lies within ``measuring_range_mm``
    along its beam, then read again. ``reply`` is what the sensor sent.
    """

    def __init__(self, message: str, *, reply: str = "") -> None:
        super().__init__(message)
        self.reply = reply


class SensorAlarmError(DeviceError):
    """The distance sensor reports an alarm of its own (amplifier or head error, laser stopped).

    ``reply`` is what it sent; the message says what to check at the sensor.
    """

    def __init__(self, message: str, *, reply: str = "") -> None:
        super().__init__(message)
        self.reply = reply


DISTANCE_STATES = ("ok", "out_of_range", "alarm")
"""What :class:`DistanceSensorStatus` ``state`` can be."""


@dataclass(frozen=True)
class DistanceSensorStatus:
    """What the distance sensor reports now: ``state`` one of ``DISTANCE_STATES``; ``text`` says it in
    words (the sensor's own reply where it has one)."""

    state: str
    text: str = ""

    def __post_init__(self) -> None:
        if self.state not in DISTANCE_STATES:
            raise ValueError(f"state must be one of {DISTANCE_STATES}, got {self.state!r}")

    @property
    def ok(self) -> bool:
        return self.state == "ok"


@runtime_checkable
class DistanceSensor(Protocol):
    """A one-point distance sensor (a laser displacement sensor beside the camera), in mm.

    ``read_mm`` returns one distance from the sensor's reference point along its beam, or raises: never a
    made-up number. No valid distance raises :class:`OutOfRangeError`, an alarm of the sensor
    :class:`SensorAlarmError`, an unparseable or refused reply ``DeviceProtocolError``, no reply
    ``DeviceTimeoutError``, a lost link ``DeviceConnectionError`` (``connect()`` again).
    ``measuring_range_mm`` is ``(near, far)``: distances it can measure.
    """

    @property
    def measuring_range_mm(self) -> tuple[float, float]:
        """(near, far) limits of the measuring range, mm from the sensor's reference point."""

    def connect(self) -> None:
        """Open the link and check that the sensor answers."""

    def close(self) -> None:
        """Release the link; safe to call twice."""

    def read_mm(self) -> float:
        """One distance (mm) measured now."""

    def status(self) -> DistanceSensorStatus:
        """Whether a valid distance is available now (ok), or why not (out_of_range, alarm)."""

    def identity(self) -> DeviceIdentity:
        """Model, serial, port and firmware as far as the sensor (or its configuration) says."""


__all__ = [
    "DISTANCE_STATES",
    "JOINT_COUNT",
    "PIXEL_FORMATS",
    "Camera",
    "CameraStatus",
    "Connectable",
    "ControllerError",
    "DeviceBusyError",
    "DeviceConnectionError",
    "DeviceError",
    "DeviceIdentity",
    "DeviceProtocolError",
    "DeviceTimeoutError",
    "DistanceSensor",
    "DistanceSensorStatus",
    "ExposureAdjustable",
    "Frame",
    "FrameError",
    "FrameRateAdjustable",
    "GainAdjustable",
    "ImageArray",
    "InvalidSettingError",
    "MotionRejectedError",
    "MotionStoppedError",
    "NotSupportedError",
    "OperatorCancelledError",
    "OutOfRangeError",
    "Robot",
    "RobotPosition",
    "RobotStatus",
    "Roi",
    "RoiSelectable",
    "SensorAlarmError",
    "StopLatchedError",
    "TablePosition",
    "XYTable",
    "average_frames",
    "grab_frames",
]
