"""Capture images as lossless PNG files beside the database, written atomically.

A file is first written under a temporary name in its final directory, fsynced, renamed over the final
name and the directory fsynced: after a crash there is either the whole image or none, never a
half-written one under the final name. Any OSError (ENOSPC, EIO, EACCES ...) removes the temporary
file and becomes a :class:`RecordWriteError`; the caller commits the row only after this returned.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import uuid
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from station.imageio import ImageFileError, decode_image, read_file_bytes
from station.record._errors import RecordError, RecordWriteError

# zlib level 1 for speed. Camera frames are noisy, so LZ77 matching finds little: for 8-bit frames
# Huffman coding alone is both faster and smaller (a 640x480 sim frame: 95 kB against 125 kB);
# 16-bit frames compress better with the default strategy (their high bytes repeat).
_LEVEL_1 = [cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY]
_PNG_OPTIONS = {
    "uint8": [*_LEVEL_1, cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY],
    "uint16": [*_LEVEL_1, cv2.IMWRITE_PNG_STRATEGY_DEFAULT],
}
IMAGE_DTYPES = ("uint8", "uint16")


def check_image(image: object) -> npt.NDArray[np.uint8] | npt.NDArray[np.uint16]:
    """The image as given when it is a 2-D uint8 or uint16 array; a ValueError naming the problem else."""
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image must be a numpy array, not {type(image).__name__}")
    if image.ndim != 2 or image.dtype.name not in IMAGE_DTYPES:
        raise ValueError(
            f"image must be 2-D uint8 or uint16 (grey, as the camera gives it), not {image.ndim}-D "
            f"{image.dtype.name} of shape {image.shape}"
        )
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"image is empty (shape {image.shape})")
    return image


def encode_png(image: npt.NDArray[np.uint8] | npt.NDArray[np.uint16]) -> bytes:
    """Lossless PNG bytes of a grey 8- or 16-bit image (16 bits kept)."""
    ok, buffer = cv2.imencode(".png", image, _PNG_OPTIONS[image.dtype.name])
    if not ok:
        raise RecordError(f"OpenCV could not encode a {image.dtype.name} {image.shape} image as PNG")
    return buffer.tobytes()


def fsync_dir(directory: Path) -> None:
    fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        written = os.write(fd, view)
        view = view[written:]


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically and durably (temp name, fsync, rename, fsync dir)."""
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        if not path.parent.is_dir():
            path.parent.mkdir(parents=True)
            fsync_dir(path.parent.parent)  # the new directory's entry is durable too
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        try:
            _write_all(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
        fsync_dir(path.parent)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise RecordWriteError(str(path), exc) from exc


def sha256_file(path: Path) -> str:
    """Hex sha256 of a file's bytes, read in chunks."""
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def read_bytes_checked(path: Path, sha256: str) -> bytes:
    """A stored image's bytes, read through the station's front door for image files
    (``station/imageio.py``: a regular file, capped), after checking them against the recorded sha256."""
    try:
        data = read_file_bytes(path, what="image file")
    except ImageFileError as exc:
        raise RecordError(
            f"capture image {path} cannot be read: {exc.reason}; restore it from a backup or an export"
        ) from exc
    actual = hashlib.sha256(data).hexdigest()
    if actual != sha256:
        raise RecordError(
            f"capture image {path} changed since it was recorded (sha256 {actual[:12]}..., recorded "
            f"{sha256[:12]}...); restore the original from a backup or an export"
        )
    return data


def read_checked(path: Path, sha256: str) -> npt.NDArray[np.uint8] | npt.NDArray[np.uint16]:
    """Decode a stored image after checking its bytes against the recorded sha256."""
    data = read_bytes_checked(path, sha256)
    try:
        return decode_image(data, name=path).image
    except ImageFileError as exc:
        raise RecordError(f"capture image {path} cannot be decoded: {exc.reason}") from exc
