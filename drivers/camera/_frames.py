"""Checks shared by the camera drivers: pixel formats, image size and byte count of a delivered frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from station.devices import PIXEL_FORMATS, FrameError, ImageArray


@dataclass(frozen=True)
class Layout:
    """The image a camera was told to deliver."""

    width: int
    height: int
    pixel_format: str

    @property
    def bytes_per_pixel(self) -> int:
        return 2 if self.pixel_format == "Mono16" else 1

    @property
    def dtype(self) -> type[np.uint8] | type[np.uint16]:
        return np.uint16 if self.pixel_format == "Mono16" else np.uint8

    @property
    def nbytes(self) -> int:
        return self.width * self.height * self.bytes_per_pixel

    def describe(self) -> str:
        return f"{self.width}x{self.height} {self.pixel_format} ({self.nbytes} bytes)"


def check_pixel_format(pixel_format: str) -> str:
    """Return ``pixel_format`` if the station supports it, else ValueError naming the choices."""
    if pixel_format not in PIXEL_FORMATS:
        raise ValueError(f"pixel_format must be one of {', '.join(PIXEL_FORMATS)}, got {pixel_format!r}")
    return pixel_format


def image_from_bytes(data: bytes | memoryview, layout: Layout, *, source: str) -> ImageArray:
    """A read-only 2-D image from raw little-endian pixel bytes; FrameError on a short or long frame."""
    raw = bytes(data)  # a copy unless it already is an immutable bytes object: never aliases a reused buffer
    got = len(raw)
    if got != layout.nbytes:
        raise FrameError(
            f"{source}: corrupt frame, expected {layout.describe()}, got {got} bytes; check the cable and "
            "that nothing else changed the camera's size or format",
            expected_bytes=layout.nbytes,
            got_bytes=got,
        )
    if layout.pixel_format == "Mono16":
        image16 = np.frombuffer(raw, dtype="<u2").astype(np.uint16, copy=False)
        return image16.reshape(layout.height, layout.width)
    return np.frombuffer(raw, dtype=np.uint8).reshape(layout.height, layout.width)
