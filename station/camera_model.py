"""The station's camera model: camera matrix, distortion coefficients and the image size they hold for.

Accepted files: JSON ``{"camera_matrix": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "dist_coeffs":
[k1, k2, p1, p2, k3]}`` (``distortion_coefficients`` is accepted too), or the YAML/XML that
``cv2.FileStorage`` writes with nodes ``camera_matrix`` and ``dist_coeffs`` /
``distortion_coefficients`` (what ``cv2.calibrateCamera`` results are usually saved as).

Since issue 23 a model also says which frames it holds for: ``image_width`` and ``image_height`` (px,
the names OpenCV's own calibration sample writes), and a calibrated one carries its standard
uncertainties (``sigma``: ``fx``, ``fy``, ``cx``, ``cy`` in px, the distortion coefficients by name) and
where it came from (``source``, free-form). Files without them still load (``image_size`` None); a model
whose size differs from the camera's frames is refused by :func:`check_image_size`, which says what to
do.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

__all__ = [
    "CameraIntrinsics",
    "CameraModelError",
    "ImageSizeError",
    "check_image_size",
    "load_camera_model",
    "read_camera_model",
    "write_camera_model",
]

FloatArray = npt.NDArray[np.float64]

#: Names of OpenCV's distortion coefficients, in order (the first 4, 5, 8, 12 or 14 are used).
DIST_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tx", "ty")

RECALIBRATE = "station run camera-calibration"


class CameraModelError(ValueError):
    """A camera model file is missing, unreadable or incomplete; the message says which."""

    code = "camera_model"


class ImageSizeError(CameraModelError):
    """The camera model holds for frames of another size than the camera gives (or does not say)."""

    code = "camera_model_size"


_DIST_KEYS = ("dist_coeffs", "distortion_coefficients")


@dataclass(frozen=True)
class CameraIntrinsics:
    """A camera model: OpenCV's pinhole and distortion, with the frame size it holds for.

    Attributes
    ----------
    camera_matrix : numpy.ndarray, shape (3, 3)
        ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, px (pixel centres at integers, OpenCV's convention).
    dist_coeffs : numpy.ndarray, shape (n,)
        OpenCV's distortion coefficients ``k1, k2, p1, p2, k3, ...`` (n = 4, 5, 8, 12 or 14).
    image_size : (int, int) or None
        ``(width, height)`` of the frames it holds for, px; None for a model that does not say.
    sigma : mapping of str to float
        Standard uncertainties (k = 1) by name (``fx``, ``fy``, ``cx``, ``cy`` px, ``k1``, ...); empty
        when unknown.
    source : mapping of str to Any
        Where it came from (a calibration's id, target, view count, ...), JSON-ready; free-form.
    """

    camera_matrix: FloatArray
    dist_coeffs: FloatArray
    image_size: tuple[int, int] | None = None
    sigma: Mapping[str, float] = field(default_factory=dict)
    source: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        k, d = _checked(self.camera_matrix, self.dist_coeffs)
        object.__setattr__(self, "camera_matrix", k)
        object.__setattr__(self, "dist_coeffs", d)
        if self.image_size is not None:
            w, h = (int(v) for v in self.image_size)
            if w < 1 or h < 1 or (w, h) != tuple(self.image_size):
                raise CameraModelError(
                    f"image size must be two positive whole numbers, got {self.image_size}"
                )
            object.__setattr__(self, "image_size", (w, h))
        for name, value in self.sigma.items():
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise CameraModelError(f"sigma {name!r} must be a finite value >= 0, got {value!r}")

    @property
    def fx(self) -> float:
        return float(self.camera_matrix[0, 0])

    @property
    def fy(self) -> float:
        return float(self.camera_matrix[1, 1])

    @property
    def principal_point(self) -> tuple[float, float]:
        """``(cx, cy)``, px."""
        return float(self.camera_matrix[0, 2]), float(self.camera_matrix[1, 2])

    def coefficient(self, name: str) -> float:
        """One distortion coefficient by OpenCV's name (``k1``, ``p2``, ...); 0 when the model lacks it."""
        i = DIST_NAMES.index(name)
        return float(self.dist_coeffs[i]) if i < self.dist_coeffs.size else 0.0

    def to_dict(self) -> dict[str, Any]:
        """The JSON file's content."""
        out: dict[str, Any] = {
            "camera_matrix": self.camera_matrix.tolist(),
            "dist_coeffs": self.dist_coeffs.tolist(),
        }
        if self.image_size is not None:
            out["image_width"], out["image_height"] = self.image_size
        if self.sigma:
            out["sigma"] = {k: float(v) for k, v in self.sigma.items()}
        if self.source:
            out["source"] = dict(self.source)
        return out

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any], *, name: str = "camera model") -> CameraIntrinsics:
        """Inverse of :meth:`to_dict`; ``name`` prefixes error messages (a file's path)."""
        if not isinstance(doc, Mapping):
            raise CameraModelError(f"{name}: expected a JSON object with camera_matrix and dist_coeffs")
        dist_key = next((k for k in _DIST_KEYS if k in doc), None)
        if "camera_matrix" not in doc or dist_key is None:
            raise CameraModelError(f"{name}: expected keys camera_matrix and dist_coeffs")
        size = _size(doc.get("image_width"), doc.get("image_height"), name)
        sigma = doc.get("sigma") or {}
        source = doc.get("source") or {}
        if not isinstance(sigma, Mapping) or not isinstance(source, Mapping):
            raise CameraModelError(f"{name}: sigma and source must be JSON objects")
        try:
            return cls(doc["camera_matrix"], doc[dist_key], size, dict(sigma), dict(source))
        except CameraModelError as exc:
            raise CameraModelError(f"{name}: {exc}") from None


def _checked(K: object, dist: object) -> tuple[FloatArray, FloatArray]:
    try:
        k = np.array(K, dtype=np.float64).reshape(3, 3)
        d = np.array(dist, dtype=np.float64).ravel()
    except (TypeError, ValueError) as exc:
        raise CameraModelError("camera_matrix must be 3x3 numbers and dist_coeffs a list") from exc
    if not (np.all(np.isfinite(k)) and np.all(np.isfinite(d))):
        raise CameraModelError("the camera model holds NaN or infinite values")
    if d.size not in (4, 5, 8, 12, 14):
        raise CameraModelError(f"{d.size} distortion coefficients; OpenCV's models have 4, 5, 8, 12 or 14")
    if not (k[0, 0] > 0 and k[1, 1] > 0) or not np.allclose(k[2], [0.0, 0.0, 1.0]):
        raise CameraModelError("camera_matrix must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
    k.setflags(write=False)
    d.setflags(write=False)
    return k, d


def _size(width: object, height: object, name: str) -> tuple[int, int] | None:
    if width is None and height is None:
        return None
    if width is None or height is None:
        raise CameraModelError(f"{name}: give both image_width and image_height (px), or neither")
    try:
        w, h = float(width), float(height)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise CameraModelError(
            f"{name}: image_width and image_height must be numbers, got {width!r}, {height!r}"
        ) from None
    if not (w.is_integer() and h.is_integer() and w >= 1 and h >= 1):
        raise CameraModelError(f"{name}: image_width and image_height must be whole numbers of px >= 1")
    return int(w), int(h)


def read_camera_model(path: str | Path) -> CameraIntrinsics:
    """Read a camera model file (JSON, or OpenCV's YAML/XML); :class:`CameraModelError` says what is wrong."""
    p = Path(path)
    if not p.is_file():
        raise CameraModelError(f"{p}: no such camera model file")
    if p.suffix.lower() == ".json":
        try:
            doc = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise CameraModelError(f"{p}: not readable JSON: {exc}") from exc
        return CameraIntrinsics.from_dict(doc, name=str(p))
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
    try:
        if not fs.isOpened():
            raise CameraModelError(f"{p}: not a JSON, YAML or XML file OpenCV can read")
        K = fs.getNode("camera_matrix").mat()
        dist = next((fs.getNode(k).mat() for k in _DIST_KEYS if not fs.getNode(k).empty()), None)
        width = fs.getNode("image_width").real() if not fs.getNode("image_width").empty() else None
        height = fs.getNode("image_height").real() if not fs.getNode("image_height").empty() else None
    finally:
        fs.release()
    if K is None or dist is None:
        raise CameraModelError(f"{p}: expected nodes camera_matrix and dist_coeffs")
    try:
        return CameraIntrinsics(
            np.asarray(K, dtype=np.float64), np.asarray(dist, dtype=np.float64), _size(width, height, str(p))
        )
    except CameraModelError as exc:
        raise CameraModelError(f"{p}: {exc}") from None


def load_camera_model(path: str | Path) -> tuple[list[list[float]], list[float]]:
    """Return ``(camera_matrix, dist_coeffs)`` as lists, ready for ``MeasureParams``."""
    model = read_camera_model(path)
    return model.camera_matrix.tolist(), model.dist_coeffs.tolist()


def write_camera_model(model: CameraIntrinsics, path: str | Path) -> Path:
    """Write ``model`` as JSON atomically (temporary file, fsync, rename); returns the path."""
    p = Path(path)
    if p.suffix.lower() != ".json":
        raise CameraModelError(f"{p}: a camera model is written as .json")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".camera-", suffix=".json", dir=p.parent)
    except OSError as exc:
        raise CameraModelError(f"{p}: cannot write the camera model there: {exc.strerror}") from exc
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(model.to_dict(), f, indent=2)
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def check_image_size(model: CameraIntrinsics, width: int, height: int, *, require_size: bool = True) -> None:
    """Refuse a model that does not hold for ``width`` x ``height`` frames.

    Raises :class:`ImageSizeError` naming both sizes and what to do when the model was made for another
    size (a changed region of interest or binning moves and scales the pixels), and, with
    ``require_size``, when the model does not say which size it holds for (a file from before image
    sizes were recorded).
    """
    if model.image_size is None:
        if require_size:
            raise ImageSizeError(
                f"the camera model does not say which image size it holds for (the camera gives {width} x "
                f"{height} px): add image_width = {width} and image_height = {height} to it if it was made "
                f"for these frames, or calibrate the camera ({RECALIBRATE})"
            )
        return
    if model.image_size != (width, height):
        mw, mh = model.image_size
        raise ImageSizeError(
            f"the camera model holds for {mw} x {mh} px frames but the camera gives {width} x {height} px "
            f"(a changed region of interest or binning): set the camera back to {mw} x {mh} px, or "
            f"calibrate it at this size ({RECALIBRATE})"
        )
