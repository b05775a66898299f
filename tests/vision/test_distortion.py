"""Lens-distortion correction from a stored OpenCV camera model (precise mode, off by default)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from sim.artifact import pose_for_center_px, render
from station.camera_model import CameraModelError, load_camera_model
from station.vision import EdgeNotFoundError, MeasureParams, measure

K = np.array([[900.0, 0.0, 319.5], [0.0, 900.0, 239.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.25, 0.1, 0.0, 0.0, 0.0])


def distort(image: np.ndarray) -> np.ndarray:
    """The image a lens with (K, DIST) would give: each distorted pixel samples the ideal image."""
    h, w = image.shape
    grid = np.stack(np.meshgrid(np.arange(w), np.arange(h)), axis=-1).reshape(-1, 1, 2).astype(np.float64)
    ideal = cv2.undistortPoints(grid, K, DIST, P=K).reshape(h, w, 2).astype(np.float32)
    return cv2.remap(image, ideal[..., 0], ideal[..., 1], cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)


def test_camera_model_straightens_distorted_edges_and_recovers_the_centre(tmp_path: Path) -> None:
    image, truth = render(pose_for_center_px(420.0, 160.0, rotation_deg=3.0), rng=np.random.default_rng(0))
    warped = distort(image)
    model_file = tmp_path / "camera.json"
    model_file.write_text(json.dumps({"camera_matrix": K.tolist(), "dist_coeffs": DIST.tolist()}))
    k, d = load_camera_model(model_file)
    corrected = measure(warped, MeasureParams(camera_matrix=k, dist_coeffs=d))
    assert np.hypot(*np.subtract(corrected.center_px, truth.center_px)) < 0.03
    assert max(e.rms_px for e in corrected.edges.values()) < 0.1
    # without the model this lens bends the edges by pixels: no straight edge, and the error says so
    with pytest.raises(EdgeNotFoundError, match="not on a line"):
        measure(warped, MeasureParams())


def test_camera_model_yaml_from_opencv_and_bad_files(tmp_path: Path) -> None:
    yml = tmp_path / "camera.yml"
    fs = cv2.FileStorage(str(yml), cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", DIST.reshape(1, 5))
    fs.release()
    k, d = load_camera_model(yml)
    np.testing.assert_allclose(k, K)
    np.testing.assert_allclose(d, DIST)
    with pytest.raises(CameraModelError, match="no such camera model file"):
        load_camera_model(tmp_path / "none.json")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"camera_matrix": K.tolist(), "dist_coeffs": [0.1, 0.2, 0.3]}))
    with pytest.raises(CameraModelError, match="3 distortion coefficients"):
        load_camera_model(bad)
    bad.write_text(json.dumps({"camera_matrix": K.tolist()}))
    with pytest.raises(CameraModelError, match="expected keys"):
        load_camera_model(bad)
    with pytest.raises(ValueError, match="need a camera_matrix"):
        MeasureParams(dist_coeffs=DIST.tolist())
