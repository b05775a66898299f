"""A coarse estimate of the cross's in-plane rotation from the image gradients.

Used to explain a failure: the directional operators of paper mode assume grooves near the image axes,
so a cross turned by ~45 deg yields edges that are not straight lines; this estimate turns that into
"rotated by 44 deg" instead of "no edges". The gradient angles of two perpendicular grooves are
theta + k*90 deg, so their fourfold angle 4*phi is the same for all four edges: the magnitude-weighted
circular mean of 4*phi, divided by 4, is the rotation in (-45, 45] deg.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt


def dominant_rotation_deg(gray: npt.NDArray[np.uint8] | npt.NDArray[np.float32]) -> tuple[float, float]:
    """Return ``(rotation_deg, strength)``; strength in [0, 1] (1: all gradients agree)."""
    # Scharr's kernel is the most rotation-invariant 3x3 derivative; a light blur keeps sharp edges from
    # biasing the angle toward the pixel axes (Sobel on a sharp edge is off by ~1-2 deg at 20 deg).
    img = cv2.GaussianBlur(gray.astype(np.float32), (5, 5), 1.0)
    gx = cv2.Scharr(img, cv2.CV_32F, 1, 0)
    gy = cv2.Scharr(img, cv2.CV_32F, 0, 1)
    # With z = gx + i gy, weight |z|^4 and fourfold angle: sum |z|^4 e^(4i phi) = sum z^4 = sum (z^2)^2,
    # and sum |z|^4 = sum |z^2|^2: three dot products of z^2's parts, no division per pixel.
    re2 = (gx * gx - gy * gy).ravel()
    im2 = (2.0 * gx * gy).ravel()
    rr, ii, ri = float(re2 @ re2), float(im2 @ im2), float(re2 @ im2)
    total = rr + ii
    if total <= 0:
        return 0.0, 0.0
    cx = (rr - ii) / total
    sx = 2.0 * ri / total
    return math.degrees(math.atan2(sx, cx)) / 4.0, math.hypot(cx, sx)
