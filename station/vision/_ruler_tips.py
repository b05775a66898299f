"""The ruler's axis across it: from the graduation lines' tips at ``t = +/- line_length / 2``.

Each tip zone is cut into strips one pixel wide across the ruler. In each strip the graduations'
own profile (the phase stage's template, at the fitted phase) is fitted to the grey levels: its
coefficient is the graduations' contrast there, full inside the lines, none beyond their tips.
Across the zone it is a blurred step whose middle is the tips' line; a model
``(p0 + p1 (t - t_e)) Phi((t_e - t) / sigma)`` (mirrored for the other tip) fitted to it gives
``t_e``, unbiased by a symmetric blur and by a contrast that changes across the zone. Each zone is
fitted in two halves along the ruler, so that the tips give the axis's direction as well as its
place: the axis is midway between the two tips' lines.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.special import ndtr

from station.vision._kernels import compiled

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Tips:
    """The tips' lines across the ruler: ``t`` (periods, in the frame) of the lower and upper tips at
    ``s_left`` and ``s_right`` (the two halves of the tip zones' stretch), and the steps' blur."""

    lower: tuple[float, float]
    upper: tuple[float, float]
    s_left: float
    s_right: float
    blur: float

    def axis(self, s: float) -> float:
        """``t`` of the ruler's axis (midway between the tips) at ``s``."""
        a = 0.5 * (self.lower[0] + self.upper[0])
        b = 0.5 * (self.lower[1] + self.upper[1])
        return a + (b - a) * (s - self.s_left) / (self.s_right - self.s_left)

    @property
    def slope(self) -> float:
        """Change of the axis's ``t`` per period of ``s``."""
        return (self.axis(self.s_right) - self.axis(self.s_left)) / (self.s_right - self.s_left)

    @property
    def width(self) -> float:
        """Mean tip-to-tip distance (periods)."""
        return 0.5 * (self.upper[0] - self.lower[0] + self.upper[1] - self.lower[1])


def contrasts(
    bins: FloatArray, strip: npt.NDArray[np.int64], strips: int, profile: FloatArray, noise_floor: float
) -> tuple[FloatArray, FloatArray]:
    """Each strip's graduation contrast and mean ``t``.

    The least-squares coefficient of the graduations' profile (``profile``: the template at each
    bin's ``s``) in the strip's grey levels, with a constant background: exact whatever the pixels'
    sampling of the period, as the template is the graduations' own shape. Bins more than 4 robust
    sigmas (at least ``noise_floor`` DN per pixel) off the fit are dropped and the fits made again.

    Parameters
    ----------
    bins : (n, 6) ndarray
        The bins (``_ruler_bins.BIN_FIELDS``).
    strip : (n,) ndarray of int
        Each bin's strip, ``0 .. strips - 1``.
    strips : int
        Number of strips.
    profile : (n,) ndarray
        The template at each bin's ``s``.
    noise_floor : float
        Smallest noise assumed, DN per pixel.

    Returns
    -------
    contrast, t : ndarray, ndarray
        Per strip (NaN where a strip has too few bins).

    Notes
    -----
    The compiled kernel (``_ckernels.ruler_tip_contrasts``) does the same; this is its reference.
    """
    ck = compiled()
    if ck is not None:
        contrast, t = np.empty(strips), np.empty(strips)
        ck.ruler_tip_contrasts(
            np.ascontiguousarray(bins, dtype=np.float64),
            np.ascontiguousarray(strip, dtype=np.int64),
            np.ascontiguousarray(profile, dtype=np.float64),
            float(noise_floor),
            contrast,
            t,
        )
        return contrast, t
    n = bins[:, 0]
    level = bins[:, 1] / np.maximum(n, 1.0)
    weight = n.copy()
    contrast = np.full(strips, np.nan)
    background = np.zeros(strips)
    for _ in range(2):  # once more without the bins a speck or a scratch spoils

        def total(values: FloatArray) -> FloatArray:
            return np.asarray(np.bincount(strip, values, minlength=strips), dtype=np.float64)

        s0, s1, s2 = total(weight), total(weight * profile), total(weight * profile * profile)
        r0, r1 = total(weight * level), total(weight * level * profile)
        det = s0 * s2 - s1 * s1
        good = (np.bincount(strip, weight > 0, minlength=strips) >= 3) & (
            np.abs(det) > 1e-12 * np.maximum(s0 * s2, 1e-300)
        )
        safe = np.where(good, det, 1.0)
        background = np.where(good, (s2 * r0 - s1 * r1) / safe, np.nan)
        contrast = np.where(good, (s0 * r1 - s1 * r0) / safe, np.nan)
        residual = (level - background[strip] - contrast[strip] * profile) * np.sqrt(n)
        ok = (n > 0) & np.isfinite(residual)
        spread = max(1.4826 * float(np.median(np.abs(residual[ok]))) if ok.any() else 0.0, noise_floor)
        weight = np.where(ok & (np.abs(residual) < 4.0 * spread), n, 0.0)
    counts = np.bincount(strip, n, minlength=strips)
    t = np.bincount(strip, bins[:, 3], minlength=strips) / np.where(counts > 0, counts, np.nan)
    return contrast, t


def fit_tip(
    t: FloatArray, m: FloatArray, start: float, blur: float, *, inside_below: bool
) -> tuple[float, float]:
    """Fit the blurred step of one tip zone; returns ``(t_e, sigma)`` in the units of ``t``.

    The model is ``(p0 + p1 (t - t_e)) Phi(+/-(t_e - t) / sigma)`` over the whole zone, which
    reaches about as far beyond the tips as inside the lines, so that a mismatch of the model's
    shape (the pixel box, the strips' width) pulls ``t_e`` neither way. ``inside_below``: the lines
    lie at ``t < t_e`` (the upper tip) rather than above it. Started from the profile's half-way
    crossing (``start``, ``blur`` if it has none), then Levenberg-Marquardt.
    """
    sign = 1.0 if inside_below else -1.0
    ok = np.isfinite(t) & np.isfinite(m)
    order = np.argsort(sign * t[ok])  # from inside the lines outward
    t, m = t[ok][order], m[ok][order]
    if len(t) < 6:
        return float(start), float(blur)
    plateau = float(np.median(m[:4]))
    q = m / plateau if plateau != 0 else m
    te = float(start)
    below = np.flatnonzero(q < 0.5)
    if len(below) and below[0] > 0:
        i = int(below[0])
        te = float(t[i - 1] + (0.5 - q[i - 1]) * (t[i] - t[i - 1]) / (q[i] - q[i - 1]))
    params = np.array([te, blur, plateau, 0.0])
    ck = compiled()
    if ck is not None:  # the same loop (``_ckernels.ruler_tip_fit``)
        ck.ruler_tip_fit(np.ascontiguousarray(t), np.ascontiguousarray(m), params, sign, float(blur))
        return float(params[0]), float(params[1])

    def residual(p: FloatArray) -> tuple[FloatArray, FloatArray]:
        z = sign * (p[0] - t) / p[1]
        step = ndtr(z)
        dens = np.exp(-0.5 * z * z) / np.sqrt(2 * np.pi)
        level = p[2] + p[3] * (t - p[0])
        jac = np.column_stack(
            [level * dens * sign / p[1] - p[3] * step, -level * dens * z / p[1], step, (t - p[0]) * step]
        )
        return m - level * step, jac

    r, jac = residual(params)
    cost, damping = float(r @ r), 1e-3
    for _ in range(30):
        normal = jac.T @ jac
        step = np.linalg.solve(normal + damping * np.diag(np.diag(normal) + 1e-300), jac.T @ r)
        trial = params + step
        trial[1] = max(abs(trial[1]), 0.1 * blur)
        r_new, jac_new = residual(trial)
        cost_new = float(r_new @ r_new)
        if cost_new < cost:
            params, r, jac, cost, damping = trial, r_new, jac_new, cost_new, damping * 0.3
            if abs(step[0]) < 1e-6:
                break
        else:
            damping *= 10.0
            if damping > 1e8:
                break
    return float(params[0]), float(params[1])
