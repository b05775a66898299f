"""The map from image pixels to the ruler's frame, in graduation periods: a plane homography.

``s = A.p / C.p`` and ``t = B.p / C.p`` with ``p = (x, y, 1)`` (px, or undistorted px with a camera
model) and the rows ``A, B, C`` of ``matrix``. ``s`` counts periods along the ruler (graduation
centres at whole numbers once fitted, up to the code's offset), ``t`` periods across it from the
axis. The grating fixes ``A`` and ``C`` (its phase, period, direction and their change across the
frame: perspective); ``B`` is the direction +90 deg from the graduation normal at the pattern's
centre, at the same scale, shifted so that the line tips sit at ``t = +/- line_length / 2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class RulerFrame:
    """Image -> ruler (periods) homography, rows ``(A, B, C)``, ``C.p > 0`` over the frame."""

    matrix: FloatArray

    def map(self, x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``(s, t)`` at image points ``(x, y)`` (arrays broadcast)."""
        m = self.matrix
        xa, ya = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        den = m[2, 0] * xa + m[2, 1] * ya + m[2, 2]
        s = (m[0, 0] * xa + m[0, 1] * ya + m[0, 2]) / den
        t = (m[1, 0] * xa + m[1, 1] * ya + m[1, 2]) / den
        return np.asarray(s), np.asarray(t)

    def point(self, x: float, y: float) -> tuple[float, float]:
        """``(s, t)`` at one image point."""
        s, t = self.map(x, y)
        return float(s), float(t)

    def image_of(self, s: float, t: float) -> tuple[float, float]:
        """The image point whose ruler coordinates are ``(s, t)``."""
        p = np.linalg.solve(self.matrix, np.array([s, t, 1.0]))
        return float(p[0] / p[2]), float(p[1] / p[2])

    def gradient(self, x: float, y: float) -> tuple[FloatArray, FloatArray]:
        """``(grad s, grad t)`` at an image point, periods per px."""
        m = self.matrix
        p = np.array([x, y, 1.0])
        den = float(m[2] @ p)
        s, t = float(m[0] @ p) / den, float(m[1] @ p) / den
        return (m[0, :2] - s * m[2, :2]) / den, (m[1, :2] - t * m[2, :2]) / den

    def s_range(self, t: float, width: int, height: int, border: float = 1.0) -> tuple[float, float] | None:
        """The ``s`` interval of the line ``t = const`` inside the frame (``border`` px in), or None."""
        a, b, c = self.matrix[1] - t * self.matrix[2]  # a x + b y + c = 0
        x0, x1, y0, y1 = border, width - 1 - border, border, height - 1 - border
        points: list[tuple[float, float]] = []
        if abs(b) > 1e-15:
            points += [(x, -(a * x + c) / b) for x in (x0, x1)]
        if abs(a) > 1e-15:
            points += [(-(b * y + c) / a, y) for y in (y0, y1)]
        inside = [(x, y) for x, y in points if x0 - 1e-9 <= x <= x1 + 1e-9 and y0 - 1e-9 <= y <= y1 + 1e-9]
        if len(inside) < 2:
            return None
        values = [self.point(x, y)[0] for x, y in inside]
        return min(values), max(values)

    def s_ranges(
        self, ts: FloatArray, width: int, height: int, border: float = 1.0
    ) -> tuple[FloatArray, FloatArray]:
        """``s_range`` for many lines ``t = ts`` at once: ``(lo, hi)`` arrays, NaN where a line misses."""
        m = self.matrix
        ts = np.asarray(ts, dtype=np.float64)
        a = m[1, 0] - ts * m[2, 0]
        b = m[1, 1] - ts * m[2, 1]
        c = m[1, 2] - ts * m[2, 2]
        x0, x1, y0, y1 = border, width - 1 - border, border, height - 1 - border
        with np.errstate(divide="ignore", invalid="ignore"):
            xs = np.stack([np.full_like(ts, x0), np.full_like(ts, x1), -(b * y0 + c) / a, -(b * y1 + c) / a])
            ys = np.stack([-(a * x0 + c) / b, -(a * x1 + c) / b, np.full_like(ts, y0), np.full_like(ts, y1)])
            inside = (xs >= x0 - 1e-9) & (xs <= x1 + 1e-9) & (ys >= y0 - 1e-9) & (ys <= y1 + 1e-9)
            s, _ = self.map(xs, ys)
        s = np.where(inside & np.isfinite(s), s, np.nan)
        enough = np.sum(inside, axis=0) >= 2
        with np.errstate(all="ignore"):
            lo = np.where(enough, np.nanmin(np.where(enough, s, 0.0), axis=0), np.nan)
            hi = np.where(enough, np.nanmax(np.where(enough, s, 0.0), axis=0), np.nan)
        return lo, hi

    def stretch(
        self, t_from: float, t_to: float, width: int, height: int, border: float = 1.0
    ) -> tuple[float, float] | None:
        """The ``s`` interval over which the whole band ``t_from <= t <= t_to`` is inside the frame."""
        first = self.s_range(t_from, width, height, border)
        second = self.s_range(t_to, width, height, border)
        if first is None or second is None:
            return None
        lo, hi = max(first[0], second[0]), min(first[1], second[1])
        return (lo, hi) if hi > lo else None

    def corrected(self, e: FloatArray, s_centre: float) -> RulerFrame:
        """The frame after a small correction ``e = (e0, e1, e2, e3, e4)`` of ``s``:

        ``u' = (u + e0 + e1 u + e2 t) / (1 + e3 u + e4 t)`` with ``u = s - s_centre`` (and ``t`` divided
        by the same denominator), i.e. ``s`` moved by ``e0 + e1 u + e2 t - u (e3 u + e4 t)`` to first order.
        """
        e0, e1, e2, e3, e4 = (float(v) for v in e)
        shift = np.array([[1.0, 0.0, -s_centre], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        back = np.array([[1.0, 0.0, s_centre], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        step = np.array([[1.0 + e1, e2, e0], [0.0, 1.0, 0.0], [e3, e4, 1.0]])
        return RulerFrame(normalised(back @ step @ shift @ self.matrix))

    def squared(self, x: float, y: float) -> RulerFrame:
        """The frame with ``t`` re-derived at ``(x, y)``: ``grad t`` is ``grad s`` turned +90 deg (the
        ruler's axes are square and the pixels square), keeping ``t(x, y)``."""
        m = self.matrix.copy()
        p = np.array([x, y, 1.0])
        den = float(m[2] @ p)
        t_here = float(m[1] @ p) / den
        grad_s, _ = self.gradient(x, y)
        grad_t = np.array([-grad_s[1], grad_s[0]])
        m[1, :2] = grad_t * den + t_here * m[2, :2]
        m[1, 2] = t_here * den - float(m[1, :2] @ p[:2])
        return RulerFrame(m)

    def squared_in_plane(self, camera_matrix: FloatArray, x: float, y: float) -> RulerFrame:
        """The frame with ``t`` re-derived from the ruler's plane, keeping ``t(x, y)``: square to ``s`` and at
        its scale *on the plane* that ``s``'s perspective (the rows ``A`` and ``C``) and the pinhole
        ``camera_matrix`` (3x3, of the frame's pixel coordinates) define.

        With ``q = K^-1 p`` the pixel's ray, the plane ``n . X = d`` (unit ``n``) and the ruler's axes
        ``e_s``, ``e_t = n x e_s`` on it, ``s = (d e_s . q - s0 n . q) / (n . q)``: the row ``C K`` is
        along ``n`` and ``A K`` less its part along ``n`` along ``e_s``, its length the scale; ``B K`` is
        then ``e_t`` at that length (the handedness kept). For a view square on the ruler this is
        :meth:`squared`; on a plane tilted by ``theta`` about ``s`` it foreshortens ``t`` by
        ``cos(theta)`` as the image does, where :meth:`squared` would not (3.4 % at 15 deg).
        """
        K = np.asarray(camera_matrix, dtype=np.float64)
        m = self.matrix
        a, b_old, c = m[0] @ K, m[1] @ K, m[2] @ K
        n = c / np.linalg.norm(c)
        a_perp = a - (a @ n) * n
        e_t = np.cross(n, a_perp)  # |a_perp| long: e_s's scale
        if e_t @ b_old < 0:
            e_t = -e_t
        row = e_t @ np.linalg.inv(K)
        p = np.array([x, y, 1.0])
        den = float(m[2] @ p)
        keep = float(m[1] @ p) / den - float(row @ p) / den
        out = m.copy()
        out[1] = row + keep * m[2]
        return RulerFrame(out)

    def shifted(self, ds: float, dt: float) -> RulerFrame:
        """The frame with ``ds`` added to ``s`` and ``dt`` to ``t`` everywhere."""
        m = self.matrix.copy()
        m[0] += ds * m[2]
        m[1] += dt * m[2]
        return RulerFrame(m)

    def sheared(self, dt: float, per_s: float) -> RulerFrame:
        """The frame with ``dt + per_s * s`` added to ``t`` everywhere (a new axis across the ruler)."""
        m = self.matrix.copy()
        m[1] += dt * m[2] + per_s * m[0]
        return RulerFrame(m)

    def flipped(self) -> RulerFrame:
        """The same frame turned by 180 deg in the ruler's plane (``s -> -s``, ``t -> -t``)."""
        m = self.matrix.copy()
        m[0] = -m[0]
        m[1] = -m[1]
        return RulerFrame(m)


def normalised(matrix: FloatArray) -> FloatArray:
    """``matrix`` scaled so that its last row's last element is 1 (the frame's origin in front)."""
    return np.asarray(matrix / matrix[2, 2])
