"""The camera's interface: ``Camera``, its frames, settings and optional abilities, and
``grab_many`` written once (``grab_frames``, ``average_frames``)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from station.devices._errors import (
    DeviceConnectionError,
    DeviceError,
    DeviceProtocolError,
)
from station.devices._lifecycle import DeviceIdentity

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


__all__ = [
    "PIXEL_FORMATS",
    "Camera",
    "CameraStatus",
    "DeviceBusyError",
    "ExposureAdjustable",
    "Frame",
    "FrameError",
    "FrameRateAdjustable",
    "GainAdjustable",
    "ImageArray",
    "InvalidSettingError",
    "Roi",
    "RoiSelectable",
    "average_frames",
    "grab_frames",
]
