"""The ruler frame's correction: one small projective correction fitted to every window's phase.

The phase windows (``_ruler_phase``) each say how far the graduations sit from whole values of
``s`` in the frame; a correction ``e`` of ``RulerFrame.corrected`` (offset, scale, shear across,
two perspective terms) is fitted to all of them, each window at its centroid with its second
moments (the correction's quadratic terms averaged over the window), weighted by its information
and Tukey-robust, the perspective terms held by a prior where the view cannot tell them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.vision._kernels import compiled
from station.vision._ruler_phase import WindowPhases, Windows

FloatArray = npt.NDArray[np.float64]

#: Tukey's biweight constant (95 % efficiency on Gaussian residuals).
TUKEY_C = 4.685


@dataclass(frozen=True)
class FrameCorrection:
    """The fitted correction ``e`` of ``RulerFrame.corrected`` about ``s_centre``, and its quality.

    ``residual_rms_px``: rms of the windows' phase residuals (px); ``used``: windows kept (biweight
    above 0); ``sigma_s0``: standard uncertainty of ``e0`` (periods).
    """

    e: FloatArray
    s_centre: float
    covariance: FloatArray
    residual: FloatArray
    used: int
    scale: float


def fit_correction(
    w: Windows, phases: WindowPhases, *, perspective: float, rounds: int = 5
) -> FrameCorrection:
    """Fit the frame's correction to the windows' phases: weighted, Tukey-robust least squares.

    ``perspective``: the prior standard deviation of the perspective terms (per period): a tilt
    ``tau`` of the ruler's plane seen at ``f`` px with a period of ``P`` px changes the scale by
    ``tan(tau) P / f`` per period. It only keeps them in bounds where the view cannot tell them
    (a short stretch); elsewhere the windows decide.
    """
    ck = compiled()
    if ck is not None:  # the same fit (``_ckernels.ruler_correction``)
        fitted, covariance, residuals = np.empty(5), np.empty(25), np.empty(len(phases.delta))
        out = ck.ruler_correction(
            np.ascontiguousarray(w.moments, dtype=np.float64),
            np.ascontiguousarray(phases.delta, dtype=np.float64),
            np.ascontiguousarray(phases.info, dtype=np.float64),
            float(phases.noise_dn),
            float(perspective),
            TUKEY_C,
            rounds,
            fitted,
            covariance,
            residuals,
        )
        if out is None:
            raise np.linalg.LinAlgError("Singular matrix")
        s_centre, used, scale = out
        return FrameCorrection(
            e=fitted,
            s_centre=s_centre,
            covariance=covariance.reshape(5, 5),
            residual=residuals,
            used=used,
            scale=scale,
        )
    m = w.moments
    good = (m[:, 0] > 0) & (phases.info > 0)
    sigma = phases.noise_dn / np.sqrt(np.where(good, phases.info, 1.0))
    s_centre = float(np.average(m[good, 1], weights=1.0 / sigma[good] ** 2))
    u = m[:, 1] - s_centre
    t = m[:, 2]
    design = np.column_stack([np.ones_like(u), u, t, -(u * u + m[:, 3]), -(u * t + m[:, 4])])
    prior = np.diag([0.0, 0.0, 0.0, 1.0, 1.0]) / perspective**2
    robust = good.astype(np.float64)
    scale = 1.0
    e: FloatArray = np.zeros(5)
    cov: FloatArray = np.zeros((5, 5))
    residual: FloatArray = np.zeros(len(u))
    for _ in range(rounds):
        wts = robust / sigma**2
        cov = np.asarray(np.linalg.inv(design.T @ (design * wts[:, None]) + prior))
        e = cov @ (design.T @ (wts * phases.delta))
        residual = phases.delta - design @ e
        z = residual / sigma
        used = robust > 0
        scale = max(1.0, 1.4826 * float(np.median(np.abs(z[good])))) if used.any() else 1.0
        r = z / (TUKEY_C * scale)
        robust = np.where(good & (np.abs(r) < 1), (1 - r * r) ** 2, 0.0)
    return FrameCorrection(
        e=e,
        s_centre=s_centre,
        covariance=cov * scale**2,
        residual=residual,
        used=int(np.count_nonzero(robust > 0)),
        scale=scale,
    )
