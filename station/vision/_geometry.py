"""Stages 7-9: vertices, the projective transform and the centre (seed 3.2.5-3.2.6, eqs. 9-12)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._edges import Edge
from station.vision._errors import GeometryError, rotated_too_far

FloatArray = npt.NDArray[np.float64]
Line = tuple[float, float, float]

HORIZONTAL: tuple[Edge, Edge] = ("top", "bottom")
VERTICAL: tuple[Edge, Edge] = ("left", "right")


def normal_form(slope: float, intercept: float, *, vertical: bool) -> Line:
    """Line ``a*x + b*y = c`` with a^2 + b^2 = 1 from the seed's slope/intercept form.

    Horizontal edges: ``y = slope*x + intercept`` (b > 0). Vertical edges (fitted on the transposed
    image): ``x = slope*y + intercept`` (a > 0).
    """
    norm = math.hypot(1.0, slope)
    if vertical:
        return (1.0 / norm, -slope / norm, intercept / norm)
    return (-slope / norm, 1.0 / norm, intercept / norm)


def intersect(l1: Line, l2: Line) -> tuple[float, float]:
    """Intersection of two normal-form lines (px); GeometryError when (nearly) parallel."""
    a1, b1, c1 = l1
    a2, b2, c2 = l2
    det = a1 * b2 - a2 * b1
    if abs(det) < 1e-9:
        raise GeometryError("two edges are parallel: they cannot bound the crossing")
    return ((c1 * b2 - c2 * b1) / det, (a1 * c2 - a2 * c1) / det)


def vertices(lines: dict[Edge, Line]) -> FloatArray:
    """The four vertices (4, 2) ``(x, y)``: top-left, top-right, bottom-right, bottom-left (seed Fig. 11)."""
    return np.array(
        [
            intersect(lines["top"], lines["left"]),
            intersect(lines["top"], lines["right"]),
            intersect(lines["bottom"], lines["right"]),
            intersect(lines["bottom"], lines["left"]),
        ],
        dtype=np.float64,
    )


def square_homography(corners_px: FloatArray, width_mm: float) -> FloatArray:
    """T of eqs. 9-12 (rho = 1): maps the 4 vertices onto (0, 0), (w, 0), (w, w), (0, w), in mm.

    Solved in float64 by ``cv2.findHomography`` on exactly four points (the exact DLT solution;
    ``getPerspectiveTransform`` would round the points to float32).
    """
    w = width_mm
    square = np.array([[0.0, 0.0], [w, 0.0], [w, w], [0.0, w]])
    H, _ = cv2.findHomography(corners_px.astype(np.float64), square, 0)
    if H is None or not np.all(np.isfinite(H)):
        raise GeometryError("the four vertices are degenerate (three in a line): no projective transform")
    return np.asarray(H, dtype=np.float64)


def apply_homography(H: FloatArray, pts: FloatArray) -> FloatArray:
    """Apply a 3x3 homography to (N, 2) points."""
    ph = np.column_stack([pts, np.ones(len(pts))]) @ H.T
    return np.asarray(ph[:, :2] / ph[:, 2:3], dtype=np.float64)


def centre(H: FloatArray, width_mm: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """(center_mm, center_px) from T (seed 3.2.6).

    The mean of the four transformed vertices is the square's centre (w/2, w/2); shifting the
    transformed image origin pixel (seed pixel (1, 1) = 0-based (0, 0)) to the world origin gives
    ``center_mm = (w/2, w/2) - T(0, 0)``. In the image the centre is T^-1(w/2, w/2), the crossing of the
    quadrilateral's diagonals.
    """
    half = width_mm / 2.0
    # T(0, 0) is T's last column, dehomogenised
    h02, h12, h22 = (float(v) for v in H[:, 2])
    center_mm = (half - h02 / h22, half - h12 / h22)
    px = np.linalg.inv(H) @ np.array([half, half, 1.0])
    return center_mm, (float(px[0] / px[2]), float(px[1] / px[2]))


def edge_angle_deg(line: Line, *, vertical: bool) -> float:
    """Angle of an edge from its nominal axis (deg): positive turns image +x toward +y."""
    a, b, _ = line
    # An artifact turned by theta has u = (cos, sin) and v = (-sin, cos). A horizontal edge (normal
    # (-sin, cos)) has a = -sin, b = cos; a vertical edge (normal (cos, sin)) has a = cos, b = sin.
    if vertical:
        return math.degrees(math.atan2(b, a))
    return math.degrees(math.atan2(-a, b))


def check_cross(
    lines: dict[Edge, Line], corners: FloatArray, shape: tuple[int, int], *, max_rotation_deg: float
) -> tuple[float, tuple[float, float]]:
    """Check that the four lines form the artifact's cross; return (rotation_deg, groove widths px).

    Raises GeometryError with what is wrong: rotation beyond the mode's range, grooves not
    perpendicular, edges in the wrong order (a bright band, not a dark groove), or the crossing
    outside the frame.
    """
    angles = {e: edge_angle_deg(lines[e], vertical=e in VERTICAL) for e in lines}
    rotation = math.fsum(angles.values()) / len(angles)
    worst = max(angles.values(), key=abs)
    if abs(worst) > max_rotation_deg:
        raise rotated_too_far(worst, max_rotation_deg, seen="is", digits=1)
    h_dir = (angles["top"] + angles["bottom"]) / 2.0
    v_dir = (angles["left"] + angles["right"]) / 2.0
    if abs(h_dir - v_dir) > 10.0:
        raise GeometryError(
            f"the grooves are {90 + v_dir - h_dir:.1f} deg apart, not perpendicular: "
            "the edges found do not belong to the crossed-groove artifact"
        )
    for first, second in (HORIZONTAL, VERTICAL):
        if abs(angles[first] - angles[second]) > 5.0:
            raise GeometryError(
                f"the {first} and {second} edges differ by {abs(angles[first] - angles[second]):.1f} deg:"
                " a groove's edges must be parallel"
            )
    xs, ys = corners[:, 0].tolist(), corners[:, 1].tolist()
    cx, cy = sum(xs) / len(xs), sum(ys) / len(ys)
    widths = []
    for (first, second), name in ((HORIZONTAL, "horizontal"), (VERTICAL, "vertical")):
        a1, b1, c1 = lines[first]
        a2, b2, c2 = lines[second]
        # offsets of the two edges from the crossing along the first edge's normal
        p1 = c1 - (a1 * cx + b1 * cy)
        p2 = (c2 - (a2 * cx + b2 * cy)) * (1.0 if a1 * a2 + b1 * b2 > 0 else -1.0)
        width = p2 - p1
        if width <= 1.0:
            raise GeometryError(
                f"the {name} groove's edges are in the wrong order or {width:.1f} px apart: "
                "no dark groove between them (is the image inverted or the artifact upside down?)"
            )
        widths.append(float(width))
    h, w = shape
    if not (all(0 <= v <= w - 1 for v in xs) and all(0 <= v <= h - 1 for v in ys)):  # NaN fails too
        raise GeometryError("the crossing is not inside the frame: move the camera over the crossing")
    return rotation, (widths[0], widths[1])
