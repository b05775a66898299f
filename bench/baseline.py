"""The plain-OpenCV approach a user would write instead of this project: Canny + Hough + cv2.fitLine.

Edges by Canny; the four strongest distinct Hough lines, two near each image axis; the Canny pixels
within 3 px of each line refined by ``cv2.fitLine`` with Huber weights; vertices by intersection;
``cv2.getPerspectiveTransform`` onto the groove-width square; the centre as the image of the square's
centre. Nothing of the station's measurement core is used.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


class BaselineError(ValueError):
    """The baseline could not find four edges."""


def _pick_two(lines: list[tuple[float, float]], min_sep: float) -> list[tuple[float, float]]:
    picked: list[tuple[float, float]] = []
    for rho, theta in lines:  # Hough returns the strongest first
        if all(abs(rho - r) > min_sep for r, _ in picked):
            picked.append((rho, theta))
        if len(picked) == 2:
            break
    if len(picked) < 2:
        raise BaselineError("fewer than two Hough lines in a direction")
    return picked


def _refine(points: FloatArray, rho: float, theta: float) -> tuple[float, float, float]:
    c, s = math.cos(theta), math.sin(theta)
    near = points[np.abs(points[:, 0] * c + points[:, 1] * s - rho) < 3.0]
    if len(near) < 10:
        raise BaselineError("too few Canny pixels near a Hough line")
    fit = cv2.fitLine(near.astype(np.float32), cv2.DIST_HUBER, 0, 0.01, 0.01).ravel()
    vx, vy, x0, y0 = (float(v) for v in fit)
    a, b = -vy, vx
    return a, b, a * x0 + b * y0


def _meet(l1: tuple[float, float, float], l2: tuple[float, float, float]) -> tuple[float, float]:
    a = np.array([[l1[0], l1[1]], [l2[0], l2[1]]])
    x = np.linalg.solve(a, np.array([l1[2], l2[2]]))
    return float(x[0]), float(x[1])


def measure_baseline(
    gray: npt.NDArray[np.uint8], width_mm: float = 25.4 / 32
) -> tuple[tuple[float, float], tuple[float, float]]:
    """The crossing in px (0-based, pixel centres at integers) and in mm relative to the image origin."""
    blur = cv2.GaussianBlur(gray, (5, 5), 1.0)
    edges = cv2.Canny(blur, 40, 120)
    ys, xs = np.nonzero(edges)
    points = np.column_stack([xs, ys]).astype(np.float64)
    hough = cv2.HoughLines(edges, 1, np.pi / 360, 80)
    if hough is None:
        raise BaselineError("no Hough lines")
    found = [(float(r), float(t)) for r, t in hough[:, 0, :]]
    # normal angle theta: ~0 or ~pi for vertical lines, ~pi/2 for horizontal ones
    horizontal = [(r, t) for r, t in found if abs(t - np.pi / 2) < np.pi / 4]
    vertical = [
        (r if t < np.pi / 2 else -r, t if t < np.pi / 2 else t - np.pi)
        for r, t in found
        if abs(t - np.pi / 2) >= np.pi / 4
    ]
    h_lines = sorted(_pick_two(horizontal, 10.0), key=lambda rt: rt[0])
    v_lines = sorted(_pick_two(vertical, 10.0), key=lambda rt: rt[0])
    top, bottom = (_refine(points, r, t) for r, t in h_lines)
    left, right = (_refine(points, r, t) for r, t in v_lines)
    corners = np.array([_meet(top, left), _meet(top, right), _meet(bottom, right), _meet(bottom, left)])
    w = width_mm
    square = np.array([[0, 0], [w, 0], [w, w], [0, w]], np.float32)
    T = cv2.getPerspectiveTransform(corners.astype(np.float32), square)
    centre = cv2.perspectiveTransform(np.array([[[w / 2, w / 2]]], np.float64), np.linalg.inv(T))
    origin = cv2.perspectiveTransform(np.zeros((1, 1, 2), np.float64), T)
    center_px = (float(centre[0, 0, 0]), float(centre[0, 0, 1]))
    return center_px, (w / 2 - float(origin[0, 0, 0]), w / 2 - float(origin[0, 0, 1]))
