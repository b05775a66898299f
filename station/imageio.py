"""Reading image files for measurement, with a specific error for every way a file can be bad."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt


class ImageFileError(ValueError):
    """An image file cannot be read; ``str()`` names the file and the cause, ``reason`` the cause."""

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f"{path}: {reason}")
        self.path = path
        self.reason = reason


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"
_JPEG_START = b"\xff\xd8"
_JPEG_END = b"\xff\xd9"


def _check_complete(path: Path, data: bytes) -> None:
    """Detect truncated PNG/JPEG files before decoding (decoders may return half an image)."""
    if data.startswith(_PNG_SIGNATURE) and not data.rstrip(b"\x00").endswith(_PNG_END):
        raise ImageFileError(path, "PNG file is truncated (no IEND chunk): copy it again from its source")
    if data.startswith(_JPEG_START) and _JPEG_END not in data[-64:]:
        raise ImageFileError(path, "JPEG file is truncated (no end-of-image marker)")


def read_image(path: str | Path) -> npt.NDArray[np.uint8] | npt.NDArray[np.uint16]:
    """Read an image file as stored (8 or 16 bit, grey or colour); conversion is the core's job.

    Raises
    ------
    ImageFileError
        Missing, a directory, empty, truncated, or not an image format OpenCV can decode.
    """
    p = Path(path)
    if not p.exists():
        raise ImageFileError(p, "no such file")
    if p.is_dir():
        raise ImageFileError(p, "is a directory, not an image file")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ImageFileError(p, f"cannot be read: {exc.strerror}") from exc
    if not data:
        raise ImageFileError(p, "file is empty (0 bytes)")
    _check_complete(p, data)
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ImageFileError(p, "not an image OpenCV can decode (PNG, TIFF, BMP, PGM, JPEG ...)")
    return image  # type: ignore[return-value]


def write_image(path: str | Path, image: npt.NDArray[np.uint8] | npt.NDArray[np.uint16]) -> Path:
    """Write ``image`` losslessly (PNG by default); raises ImageFileError when it cannot."""
    p = Path(path)
    try:
        ok, buf = cv2.imencode(p.suffix or ".png", image)
    except cv2.error:
        ok = False
    if not ok:
        raise ImageFileError(p, f"OpenCV cannot encode an image as {p.suffix!r}")
    p.write_bytes(buf.tobytes())
    return p
