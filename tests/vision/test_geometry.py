"""Stages 7-9: vertices, projective transform, centre; and the input stage."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from station.vision import (
    Edge,
    InvalidImageError,
    apply_homography,
    centre,
    intersect,
    normal_form,
    square_homography,
    to_gray8,
    vertices,
)
from station.vision._geometry import edge_angle_deg

W = 0.79375


def square_lines(x0: float, y0: float, side: float) -> dict[Edge, tuple[float, float, float]]:
    return {
        "top": normal_form(0.0, y0, vertical=False),
        "bottom": normal_form(0.0, y0 + side, vertical=False),
        "left": normal_form(0.0, x0, vertical=True),
        "right": normal_form(0.0, x0 + side, vertical=True),
    }


def test_normal_form_is_unit_and_matches_slope_intercept() -> None:
    a, b, c = normal_form(0.1, 5.0, vertical=False)  # y = 0.1 x + 5
    assert_allclose(a * a + b * b, 1.0)
    for x in (0.0, 10.0, 123.4):
        assert_allclose(a * x + b * (0.1 * x + 5.0), c)
    a, b, c = normal_form(-0.2, 7.0, vertical=True)  # x = -0.2 y + 7
    for y in (0.0, 50.0):
        assert_allclose(a * (-0.2 * y + 7.0) + b * y, c)


def test_edge_angle_sign_follows_image_rotation() -> None:
    theta = np.radians(5.0)  # u = (cos, sin): turns image +x toward +y
    horizontal = normal_form(np.tan(theta), 0.0, vertical=False)
    vertical = normal_form(-np.tan(theta), 0.0, vertical=True)
    assert_allclose(edge_angle_deg(horizontal, vertical=False), 5.0)
    assert_allclose(edge_angle_deg(vertical, vertical=True), 5.0)


def test_vertices_order_and_square_transform() -> None:
    lines = square_lines(100.0, 50.0, 80.0)
    corners = vertices(lines)
    assert_allclose(corners, [[100, 50], [180, 50], [180, 130], [100, 130]])
    H = square_homography(corners, W)
    assert_allclose(apply_homography(H, corners), [[0.0, 0.0], [W, 0.0], [W, W], [0.0, W]], atol=1e-12)
    center_mm, center_px = centre(H, W)
    assert_allclose(center_px, [140, 90], atol=1e-9)
    # 80 px per 0.79375 mm: the crossing is 140 px right and 90 px below the origin pixel (0, 0)
    assert_allclose(center_mm, np.array([140.0, 90.0]) * W / 80.0, atol=1e-12)


def test_centre_is_the_diagonal_crossing_under_perspective_not_the_corner_mean() -> None:
    corners = np.array([[100.0, 50.0], [185.0, 55.0], [180.0, 130.0], [98.0, 128.0]])
    H = square_homography(corners, W)
    _, center_px = centre(H, W)
    d1 = np.cross(np.append(corners[0], 1), np.append(corners[2], 1))
    d2 = np.cross(np.append(corners[1], 1), np.append(corners[3], 1))
    x = np.cross(d1, d2)
    assert_allclose(center_px, x[:2] / x[2], atol=1e-9)
    assert np.hypot(*(np.subtract(center_px, corners.mean(axis=0)))) > 0.1


def test_moving_the_artifact_by_d_moves_center_mm_by_d() -> None:
    side = 80.0
    before = centre(square_homography(vertices(square_lines(100, 50, side)), W), W)[0]
    after = centre(square_homography(vertices(square_lines(103, 48, side)), W), W)[0]
    assert_allclose(np.subtract(after, before), np.array([3.0, -2.0]) * W / side, atol=1e-12)


def test_intersect_parallel_lines_is_an_error() -> None:
    with pytest.raises(ValueError, match="parallel"):
        intersect((0.0, 1.0, 5.0), (0.0, 1.0, 9.0))


def test_to_gray8_converts_explicitly_and_rejects_what_it_cannot_read() -> None:
    g = np.full((100, 120), 77, np.uint8)
    assert to_gray8(g) is g or np.array_equal(to_gray8(g), g)
    assert to_gray8(np.full((100, 120), 65535, np.uint16)).max() == 255
    assert to_gray8(np.full((100, 120), 257 * 77, np.uint16)).max() == 77
    bgr = np.zeros((100, 120, 3), np.uint8)
    bgr[..., 1] = 200
    assert abs(int(to_gray8(bgr)[0, 0]) - round(0.587 * 200)) <= 1
    assert to_gray8(np.zeros((100, 120, 1), np.uint8)).shape == (100, 120)
    cases = [
        (np.zeros((0, 0), np.uint8), "empty"),
        (np.zeros((100, 120), np.float32), "dtype float32"),
        (np.zeros((100, 120, 2), np.uint8), "2 channels"),
        (np.zeros((10, 10), np.uint8), "at least 64x64"),
        (np.zeros((2, 100, 120, 3), np.uint8), "2-D"),
        ([[1, 2], [3, 4]], "numpy array"),
    ]
    for bad, message in cases:
        with pytest.raises(InvalidImageError, match=message):
            to_gray8(bad)
