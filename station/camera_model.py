"""Reading a stored OpenCV camera model (camera matrix and distortion coefficients).

Accepted files: JSON ``{"camera_matrix": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "dist_coeffs":
[k1, k2, p1, p2, k3]}`` (``distortion_coefficients`` is accepted too), or the YAML/XML that
``cv2.FileStorage`` writes with nodes ``camera_matrix`` and ``dist_coeffs`` /
``distortion_coefficients`` (what ``cv2.calibrateCamera`` results are usually saved as).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np


class CameraModelError(ValueError):
    """A camera model file is missing, unreadable or incomplete; the message says which."""


_DIST_KEYS = ("dist_coeffs", "distortion_coefficients")


def _validate(path: Path, K: object, dist: object) -> tuple[list[list[float]], list[float]]:
    try:
        k = np.asarray(K, dtype=np.float64).reshape(3, 3)
        d = np.asarray(dist, dtype=np.float64).ravel()
    except (TypeError, ValueError) as exc:
        raise CameraModelError(f"{path}: camera_matrix must be 3x3 numbers and dist_coeffs a list") from exc
    if not (np.all(np.isfinite(k)) and np.all(np.isfinite(d))):
        raise CameraModelError(f"{path}: the camera model holds NaN or infinite values")
    if d.size not in (4, 5, 8, 12, 14):
        raise CameraModelError(
            f"{path}: {d.size} distortion coefficients; OpenCV's models have 4, 5, 8, 12 or 14"
        )
    return k.tolist(), d.tolist()


def load_camera_model(path: str | Path) -> tuple[list[list[float]], list[float]]:
    """Return ``(camera_matrix, dist_coeffs)`` as lists, ready for ``MeasureParams``."""
    p = Path(path)
    if not p.is_file():
        raise CameraModelError(f"{p}: no such camera model file")
    if p.suffix.lower() == ".json":
        try:
            doc = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise CameraModelError(f"{p}: not readable JSON: {exc}") from exc
        dist_key = next((k for k in _DIST_KEYS if k in doc), None)
        if not isinstance(doc, dict) or "camera_matrix" not in doc or dist_key is None:
            raise CameraModelError(f"{p}: expected keys camera_matrix and dist_coeffs")
        return _validate(p, doc["camera_matrix"], doc[dist_key])
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
    try:
        if not fs.isOpened():
            raise CameraModelError(f"{p}: not a JSON, YAML or XML file OpenCV can read")
        K = fs.getNode("camera_matrix").mat()
        dist = next((fs.getNode(k).mat() for k in _DIST_KEYS if not fs.getNode(k).empty()), None)
    finally:
        fs.release()
    if K is None or dist is None:
        raise CameraModelError(f"{p}: expected nodes camera_matrix and dist_coeffs")
    return _validate(p, K, dist)
