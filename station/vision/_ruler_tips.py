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


def modulation(bins: FloatArray, profile: FloatArray, noise_floor: float) -> tuple[float, float]:
    """One strip's graduation contrast and mean ``t``: the least-squares coefficient of the
    graduations' profile (``profile``: the template at each bin's ``s``) in the strip's grey levels,
    with a constant background. Exact whatever the pixels' sampling of the period, as the template
    is the graduations' own shape. Bins more than 4 robust sigmas (at least ``noise_floor`` DN per
    pixel) off the fit are dropped and the fit made again.
    """
    n = bins[:, 0]
    total = float(n.sum())
    ok = n > 0
    if total <= 0 or ok.sum() < 3:
        return float("nan"), float("nan")
    level = bins[ok, 1] / n[ok]
    x = np.column_stack([np.ones(int(ok.sum())), profile[ok]])
    weight = n[ok]
    coef = np.zeros(2)
    for _ in range(2):  # once more without the bins a speck or a scratch spoils
        normal = x.T @ (x * weight[:, None])
        if abs(np.linalg.det(normal)) < 1e-12 * max(float(np.trace(normal)) ** 2, 1e-300):
            return float("nan"), float("nan")
        coef = np.linalg.solve(normal, x.T @ (weight * level))
        residual = (level - x @ coef) * np.sqrt(n[ok])
        spread = max(1.4826 * float(np.median(np.abs(residual))), noise_floor)
        weight = n[ok] * (np.abs(residual) < 4.0 * spread)
    return float(coef[1]), float(bins[:, 3].sum()) / total


def fit_tip(
    t: FloatArray, m: FloatArray, start: float, blur: float, *, inside_below: bool
) -> tuple[float, float]:
    """Fit the blurred step of one tip zone; returns ``(t_e, sigma)`` in the units of ``t``.

    ``inside_below``: the lines lie at ``t < t_e`` (the upper tip) rather than above it.
    """
    sign = 1.0 if inside_below else -1.0
    ok = np.isfinite(t) & np.isfinite(m)
    t_all, m_all = t[ok], m[ok]
    t, m = t_all, m_all
    inside = sign * (start - t) > 3 * blur
    p0 = float(np.median(m[inside])) if inside.any() else float(np.max(m))
    params = np.array([start, blur, p0, 0.0])
    for _ in range(12):
        te, sg, a0, a1 = params
        sg = max(abs(sg), 1e-6)
        z = sign * (te - t) / sg
        step = ndtr(z)
        dens = np.exp(-0.5 * z * z) / np.sqrt(2 * np.pi)
        level = a0 + a1 * (t - te)
        model = level * step
        jac = np.column_stack(
            [
                level * dens * sign / sg - a1 * step,
                -level * dens * z / sg,
                step,
                (t - te) * step,
            ]
        )
        delta, *_ = np.linalg.lstsq(jac, m - model, rcond=None)
        params = params + delta
        # a window symmetric about the step, as wide as the zone allows on its short side
        reach = min(float(t_all.max()) - params[0], params[0] - float(t_all.min()))
        near = np.abs(t_all - params[0]) <= reach
        if near.sum() >= 6:
            t, m = t_all[near], m_all[near]
        if abs(delta[0]) < 1e-9:
            break
    return float(params[0]), float(abs(params[1]))
