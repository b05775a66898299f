"""The renderer's edges are where Truth says, to far better than 0.001 px, measured from the images.

Two independent checks:

* the analytic pixel-box average of a blurred step (``box_step``) against brute-force quadrature
  over the pixel square (and exact polygon areas without blur);
* edge positions measured from ``render_ideal`` images by the area integral of the profile across
  each edge, which for a straight blurred step is exact whatever the blur: summing a column of
  pixel values from deep in the land to deep in the groove gives the land length in that column
  strip, i.e. the edge's position at the column centre. Lines fitted to those points, intersected,
  must give ``Truth.corners_px``.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pytest
from numpy.testing import assert_allclose
from scipy.special import ndtr

from sim._render_geometry import box_step
from sim.artifact import ArtifactSpec, CameraSpec, Pose, Truth, pose_for_center_px, render_ideal, truth_for

Array = npt.NDArray[np.float64]

# --------------------------------------------------------------------------- pixel-box integration


def _quadrature_box_step(d: float, phi: float, sigma: float, n: int = 160) -> float:
    """Average of Phi(signed distance / sigma) over the unit pixel by Gauss-Legendre quadrature."""
    nodes, weights = np.polynomial.legendre.leggauss(n)
    x, y = np.meshgrid(nodes / 2, nodes / 2)
    w = np.outer(weights, weights) / 4
    return float((ndtr((d + x * math.cos(phi) + y * math.sin(phi)) / sigma) * w).sum())


def _clipped_area(d: float, phi: float) -> float:
    """Exact area of the unit pixel on the positive side of the line (Sutherland-Hodgman clip)."""
    square = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]
    c, s = math.cos(phi), math.sin(phi)

    def side(p: tuple[float, float]) -> float:
        return d + p[0] * c + p[1] * s

    poly: list[tuple[float, float]] = []
    for p, q in zip(square, square[1:] + square[:1], strict=True):
        sp, sq = side(p), side(q)
        if sp >= 0:
            poly.append(p)
        if (sp >= 0) != (sq >= 0):
            t = sp / (sp - sq)
            poly.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    if len(poly) < 3:
        return 0.0
    xs, ys = np.array(poly).T
    return float(0.5 * abs(np.dot(xs, np.roll(ys, -1)) - np.dot(ys, np.roll(xs, -1))))


ANGLES = [0.0, 1e-7, 3e-5, 0.2, math.pi / 4, 1.1, math.pi / 2 - 1e-6, 2.5]
DISTANCES = [-2.5, -0.9, -0.35, 0.0, 0.1, 0.6, 1.7]


@pytest.mark.parametrize("sigma", [0.3, 1.0, 1.8])
@pytest.mark.parametrize("phi", ANGLES)
def test_box_step_matches_brute_force_quadrature(phi: float, sigma: float) -> None:
    c, s = abs(math.cos(phi)), abs(math.sin(phi))
    got = box_step(np.array(DISTANCES), c, s, sigma)
    expected = [_quadrature_box_step(d, phi, sigma) for d in DISTANCES]
    assert_allclose(got, expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize("phi", ANGLES)
def test_box_step_without_blur_is_the_covered_area(phi: float) -> None:
    got = box_step(np.array(DISTANCES), abs(math.cos(phi)), abs(math.sin(phi)), 0.0)
    assert_allclose(got, [_clipped_area(d, phi) for d in DISTANCES], rtol=0, atol=1e-9)


def test_box_step_is_antisymmetric_about_the_edge() -> None:
    d = np.linspace(-5, 5, 101)
    assert_allclose(box_step(d, 0.8, 0.6, 1.3) + box_step(-d, 0.8, 0.6, 1.3), 1.0, atol=1e-15)
    assert box_step(0.0, 1.0, 0.0, 1.0) == pytest.approx(0.5, abs=1e-15)


# --------------------------------------------------------------------------- edges measured from images


def _edge_points(image: Array, truth: Truth, edge: int, *, sigma: float, keep_out_mm: float) -> Array:
    """(x, y) on ``edge`` at each column (top, bottom) or row (left, right), by the area integral.

    The window runs from the groove's centreline to well inside the land; the truth lines only place
    the window (any wide window gives the same sum). Windows reaching within ``keep_out_mm`` of the
    other groove, or leaving the image, are skipped.
    """
    horizontal = edge < 2
    img = image if horizontal else image.T
    h_inv = np.linalg.inv(truth.homography)
    a, b, c = truth.lines[edge]
    centre_line = h_inv.T @ (np.array([0.0, 1.0, 0.0]) if horizontal else np.array([1.0, 0.0, 0.0]))
    ma, mb, mc = centre_line
    if not horizontal:
        a, b, ma, mb = b, a, mb, ma
    span = 7.5 * sigma + 6
    points = []
    for col in range(img.shape[1]):
        edge_at = (c - a * col) / b
        middle = round(-(mc + ma * col) / mb)
        if edge in (0, 2):  # land at smaller coordinates, groove after: sum the land
            lo, hi = int(np.floor(edge_at - span)), middle
        else:  # groove then land: sum the groove
            lo, hi = middle, int(np.ceil(edge_at + span))
        if lo < 0 or hi >= img.shape[0]:
            continue
        column = img[lo : hi + 1, col]
        pos = lo - 0.5 + (column.sum() if edge in (0, 2) else (1.0 - column).sum())
        ends = (
            np.array([[col, lo, 1.0], [col, hi, 1.0]])
            if horizontal
            else np.array([[lo, col, 1.0], [hi, col, 1.0]])
        )
        uv = ends @ h_inv.T
        other = np.abs(uv[:, 0 if horizontal else 1] / uv[:, 2])
        if (other < truth.groove_width_mm / 2 + keep_out_mm).any():
            continue
        points.append((col, pos) if horizontal else (pos, col))
    return np.array(points)


def _fit_line(points: Array) -> Array:
    """Orthogonal least-squares line (a, b, c), a x + b y = c."""
    mean = points.mean(axis=0)
    normal = np.linalg.svd(points - mean)[2][1]
    return np.array([normal[0], normal[1], normal @ mean])


def _intersect(l1: Array, l2: Array) -> Array:
    return np.asarray(np.linalg.solve(np.array([l1[:2], l2[:2]]), [l1[2], l2[2]]))


CASES = [
    ("axis-aligned", pose_for_center_px(320.3, 240.7), 1.0, ArtifactSpec()),
    (
        "rotated, tilted, narrow",
        pose_for_center_px(301.37, 222.81, rotation_deg=7.3, tilt_x_deg=0.8, tilt_y_deg=-0.6),
        1.8,
        ArtifactSpec(groove_width_mm=0.76),
    ),
    (
        "no blur, sharp corners, defocused z",
        pose_for_center_px(350.5, 260.25, rotation_deg=-9.1, tilt_x_deg=-1.0, tilt_y_deg=1.0, z_mm=0.4),
        0.0,
        ArtifactSpec(corner_radius_mm=0.0),
    ),
    ("nearly axis-aligned", Pose(x_mm=-0.195, y_mm=0.105, rotation_deg=1e-7), 0.5, ArtifactSpec()),
]


@pytest.mark.parametrize(("name", "pose", "sigma", "artifact"), CASES, ids=[c[0] for c in CASES])
def test_corners_measured_from_ideal_images_match_truth(
    name: str, pose: Pose, sigma: float, artifact: ArtifactSpec
) -> None:
    camera = CameraSpec()
    truth = truth_for(pose, artifact=artifact, camera=camera)
    image = render_ideal(pose, blur_sigma_px=sigma, artifact=artifact, camera=camera)
    keep_out = artifact.corner_radius_mm + (7.5 * sigma + 4) / camera.px_per_mm
    fitted = []
    for edge in range(4):
        points = _edge_points(image, truth, edge, sigma=sigma, keep_out_mm=keep_out)
        assert len(points) > 250
        a, b, c = truth.lines[edge]
        assert np.abs(points @ [a, b] - c).max() < 1e-6  # every column's edge point is on the true line
        fitted.append(_fit_line(points))
    top, bottom, left, right = fitted
    corners = np.array(
        [_intersect(top, left), _intersect(top, right), _intersect(bottom, right), _intersect(bottom, left)]
    )
    error = np.abs(corners - truth.corners_px).max()
    assert error < 1e-3  # the requirement; in fact ~1e-12
    assert error < 1e-8


def test_true_width_sets_the_edge_separation() -> None:
    artifact = ArtifactSpec(groove_width_mm=0.7430, nominal_groove_width_mm=0.7937)
    pose = pose_for_center_px(318.25, 241.6)
    image = render_ideal(pose, blur_sigma_px=1.2, artifact=artifact)
    dark = (1.0 - image[:, 40]).sum()  # a column far left of the vertical groove crosses one groove
    assert dark == pytest.approx(0.7430 * 100, abs=1e-9)


def test_rounded_corners_remove_the_notch_area() -> None:
    pose = pose_for_center_px(320.2, 240.4, rotation_deg=3.0)
    sharp = render_ideal(pose, blur_sigma_px=1.5, artifact=ArtifactSpec(corner_radius_mm=0.0))
    rounded = render_ideal(pose, blur_sigma_px=1.5, artifact=ArtifactSpec(corner_radius_mm=0.1))
    removed = (sharp - rounded).sum()
    assert removed == pytest.approx(4 * 10.0**2 * (1 - math.pi / 4), rel=0.01)
    assert (rounded <= sharp + 1e-12).all()  # rounding only darkens, near the crossing only
    far = np.hypot(*np.meshgrid(np.arange(640) - 320.2, np.arange(480) - 240.4)) > 80
    assert_allclose(rounded[far], sharp[far], atol=1e-12)
