"""The camera model's file format: image size and uncertainties added, old files still loading."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from station.camera_model import (
    CameraIntrinsics,
    CameraModelError,
    ImageSizeError,
    check_image_size,
    load_camera_model,
    read_camera_model,
    write_camera_model,
)

K = np.array([[6830.0, 0.0, 331.2], [0.0, 6841.5, 228.7], [0.0, 0.0, 1.0]])
DIST = np.array([-0.8, 2.0, 1e-4, -2e-4, 0.0])


def test_old_json_without_image_size_still_loads(tmp_path: Path) -> None:
    old = tmp_path / "camera.json"
    old.write_text(json.dumps({"camera_matrix": K.tolist(), "distortion_coefficients": DIST.tolist()}))
    model = read_camera_model(old)
    assert model.image_size is None
    assert model.sigma == {}
    np.testing.assert_array_equal(model.camera_matrix, K)
    k, d = load_camera_model(old)  # the measurement's loader, unchanged for callers
    assert k == K.tolist()
    assert d == DIST.tolist()


def test_opencv_yaml_with_opencv_sample_size_nodes(tmp_path: Path) -> None:
    yml = tmp_path / "camera.yml"
    fs = cv2.FileStorage(str(yml), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", DIST.reshape(1, 5))
    fs.release()
    model = read_camera_model(yml)
    assert model.image_size == (640, 480)
    np.testing.assert_allclose(model.dist_coeffs, DIST)


def test_written_model_keeps_size_sigma_and_source(tmp_path: Path) -> None:
    model = CameraIntrinsics(
        K,
        DIST,
        (640, 480),
        sigma={"fx": 1.2, "cx": 0.3, "k1": 0.01},
        source={"session_id": "abc", "views": 48},
    )
    path = write_camera_model(model, tmp_path / "camera.json")
    doc = json.loads(path.read_text())
    assert (doc["image_width"], doc["image_height"]) == (640, 480)
    back = read_camera_model(path)
    assert back.image_size == (640, 480)
    assert dict(back.sigma) == {"fx": 1.2, "cx": 0.3, "k1": 0.01}
    assert back.source["views"] == 48
    np.testing.assert_array_equal(back.camera_matrix, K)
    assert back.coefficient("k2") == 2.0
    assert back.coefficient("k4") == 0.0  # beyond the 5 coefficients held
    assert [p.name for p in tmp_path.iterdir()] == ["camera.json"]  # no temporary file left


def test_a_model_for_other_frames_is_refused_with_what_to_do() -> None:
    model = CameraIntrinsics(K, DIST, (640, 480))
    check_image_size(model, 640, 480)  # the frames it was made for
    with pytest.raises(
        ImageSizeError, match=r"holds for 640 x 480 px frames but the camera gives 1280 x 960"
    ) as err:
        check_image_size(model, 1280, 960)
    assert "station run camera-calibration" in str(err.value)
    assert err.value.code == "camera_model_size"


def test_a_model_without_size_is_refused_unless_allowed() -> None:
    model = CameraIntrinsics(K, DIST)
    with pytest.raises(ImageSizeError, match="add image_width = 640 and image_height = 480"):
        check_image_size(model, 640, 480)
    check_image_size(model, 640, 480, require_size=False)  # a caller that only warns


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ({"camera_matrix": K.tolist(), "dist_coeffs": DIST.tolist(), "image_width": 640}, "give both"),
        (
            {
                "camera_matrix": K.tolist(),
                "dist_coeffs": DIST.tolist(),
                "image_width": 640.5,
                "image_height": 480,
            },
            "whole numbers",
        ),
        ({"camera_matrix": K.tolist(), "dist_coeffs": DIST.tolist(), "sigma": {"fx": -1}}, "sigma 'fx'"),
        ({"camera_matrix": [[0, 0, 1], [0, 1, 1], [0, 0, 1]], "dist_coeffs": DIST.tolist()}, "fx, fy > 0"),
        ({"camera_matrix": K.tolist(), "dist_coeffs": [0.1, 0.2, 0.3]}, "3 distortion coefficients"),
        ({"camera_matrix": K.tolist()}, "expected keys"),
        ([1, 2, 3], "expected a JSON object"),
    ],
)
def test_bad_model_files_say_what_is_wrong(tmp_path: Path, doc: object, message: str) -> None:
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(CameraModelError, match=message) as err:
        read_camera_model(path)
    assert str(path) in str(err.value)


def test_write_refuses_a_missing_folder_and_other_formats(tmp_path: Path) -> None:
    model = CameraIntrinsics(K, DIST, (640, 480))
    with pytest.raises(CameraModelError, match="cannot write the camera model there"):
        write_camera_model(model, tmp_path / "missing" / "camera.json")
    with pytest.raises(CameraModelError, match=r"written as \.json"):
        write_camera_model(model, tmp_path / "camera.yml")
