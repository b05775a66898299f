"""The least-squares machinery of the identification: one data set, its residuals, the optimiser's call.

:class:`Problem` binds a model to the stacked captures (the crossings' and the rulers') and the sigmas;
:func:`least_squares` fits a subset of its parameters with ``scipy.optimize.least_squares``
(Levenberg-Marquardt, or trf for a robust loss); :func:`robust_weights` are a robust loss's final
weights (the IRLS view), which the covariance uses.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from station.calibration._model import CalibrationModel, Sigmas
from station.calibration._observations import CalibrationError, FloatArray, ObservationArrays
from station.calibration._ruler_observations import RulerArrays

LOSSES = ("linear", "soft_l1", "huber", "cauchy")
"""The fit's losses (``scipy.optimize.least_squares``'s names): ``linear`` is least squares; the others
weigh a residual beyond ``f_scale`` sigmas less, so that an outlier (a mismeasured capture) pulls less."""


@dataclass(frozen=True)
class Problem:
    """A model, the captures it explains and the sigmas that weight them."""

    model: CalibrationModel
    arrays: ObservationArrays
    sigmas: Sigmas
    rulers: RulerArrays | None = None

    @property
    def residual_count(self) -> int:
        """How many residuals the fit sees."""
        n = 2 * len(self.arrays) + int(self.arrays.has_z.sum())
        return n + (0 if self.rulers is None else self.rulers.residual_count)

    def residuals(self, delta: FloatArray) -> FloatArray:
        """The weighted residuals at ``delta``."""
        return self.model.weighted_residuals(delta, self.arrays, self.sigmas, rulers=self.rulers)

    def jacobian(self, delta: FloatArray, free: Sequence[int] | None = None) -> FloatArray:
        """Their Jacobian over the ``free`` columns (all by default), internal units."""
        return self.model.jacobian(delta, self.arrays, self.sigmas, free, rulers=self.rulers)


def method(loss: str) -> str:
    """The optimiser's method for ``loss``: Levenberg-Marquardt, which has no robust loss, or trf."""
    return "lm" if loss == "linear" else "trf"


def least_squares(
    problem: Problem,
    delta0: FloatArray,
    free: Sequence[int],
    max_nfev: int,
    loss: str = "linear",
    f_scale: float = 1.0,
) -> tuple[FloatArray, scipy.optimize.OptimizeResult]:
    """Fit the ``free`` parameters from ``delta0``; the full error vector and the optimiser's result."""
    model = problem.model
    idx = np.asarray(free, dtype=int)
    unit = model.internal_unit[idx]

    def full(x: FloatArray) -> FloatArray:
        d = delta0.copy()
        d[idx] = delta0[idx] + x * unit
        return d

    sol = scipy.optimize.least_squares(
        lambda x: problem.residuals(full(x)),
        np.zeros(idx.size),
        jac=lambda x: problem.jacobian(full(x), free),
        method=method(loss),
        loss=loss,
        f_scale=f_scale,
        x_scale="jac",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-10,
        max_nfev=max_nfev,
    )
    return full(sol.x), sol


def robust_weights(r: FloatArray, loss: str, f_scale: float) -> FloatArray:
    """Each (sigma-weighted) residual's weight ``rho'(z)``, ``z = (r / f_scale)^2``, at the solution: the
    iteratively reweighted least-squares view of the robust fit (1 everywhere for ``linear``)."""
    z = (np.asarray(r, dtype=float) / f_scale) ** 2
    if loss == "linear":
        return np.ones_like(z)
    if loss == "soft_l1":
        return np.asarray(1.0 / np.sqrt(1.0 + z))
    if loss == "huber":
        return np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0)))
    if loss == "cauchy":
        return np.asarray(1.0 / (1.0 + z))
    raise CalibrationError(f"unknown loss {loss!r}; one of {', '.join(LOSSES)}")


__all__ = ["LOSSES", "Problem", "least_squares", "method", "robust_weights"]
