"""Metrology: comparing measured displacements with a reference, and ISO 9283 pose repeatability.

Validation (seed section 4, Figures 13-15): the artifact moves on the X-Y table through known
displacements; the image gives measured displacements. Their frames differ by an unknown rotation (table
axes vs artifact axes), so errors are reported after a best-fit transform from commanded to measured:

* ``rigid`` (rotation + translation): the raw error, which still contains any scale error (the true
  groove width, +0/-0.002 in on 0.794 mm) and the table's non-perpendicularity;
* ``similarity`` (+ one scale): reveals the scale, the station's calibration of the true groove width;
* ``affine`` (+ shear and two scales): the seed's "well-fit parallelogram", which absorbs the table's
  non-perpendicular axes.

Repeatability (seed section 5, eqs. 13-18; ISO 9283 RP): ``RP = l_bar + 3 S_l``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class TransformFit:
    """A best-fit 2-D transform ``measured ~= A @ commanded + t`` and the residual errors.

    ``errors``: (N,) distances between measured and fitted points (units of the input);
    ``scale``: the fitted scale for ``similarity`` (1 for ``rigid``; sqrt|det A| for ``affine``);
    ``rotation_deg``: the fitted rotation.
    """

    kind: str
    A: FloatArray
    t: FloatArray
    errors: FloatArray
    scale: float
    rotation_deg: float

    @property
    def mean(self) -> float:
        return float(self.errors.mean())

    @property
    def max(self) -> float:
        return float(self.errors.max())

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.errors**2)))

    def summary_um(self) -> dict[str, float]:
        """``{"mean_um", "max_um", "rms_um", "scale"}``: the fit as ``station validate --json`` prints it."""
        return {"mean_um": self.mean, "max_um": self.max, "rms_um": self.rms, "scale": self.scale}


def _check_pairs(src: FloatArray, dst: FloatArray, minimum: int) -> None:
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 2:
        raise ValueError(f"expected two (N, 2) arrays of equal shape, got {src.shape} and {dst.shape}")
    if len(src) < minimum:
        raise ValueError(f"at least {minimum} point pairs are needed, got {len(src)}")
    if not (np.all(np.isfinite(src)) and np.all(np.isfinite(dst))):
        raise ValueError("point pairs contain NaN or infinity")


def _finish(kind: str, A: FloatArray, src: FloatArray, dst: FloatArray, scale: float) -> TransformFit:
    t = dst.mean(axis=0) - src.mean(axis=0) @ A.T
    errors = np.linalg.norm(dst - (src @ A.T + t), axis=1)
    rotation = math.degrees(math.atan2(A[1, 0] - A[0, 1], A[0, 0] + A[1, 1]))
    return TransformFit(kind, A, t, errors, scale, rotation)


def fit_rigid(src: FloatArray, dst: FloatArray, *, with_scale: bool = False) -> TransformFit:
    """Least-squares rotation (+ scale when ``with_scale``) and translation, src -> dst (Umeyama 1991).

    A proper rotation (no reflection). ``kind`` is ``rigid`` or ``similarity``.
    """
    _check_pairs(src, dst, 2)
    sc = src - src.mean(axis=0)
    dc = dst - dst.mean(axis=0)
    cov = dc.T @ sc / len(src)
    U, S, Vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(U @ Vt)) or 1.0
    D = np.diag([1.0, d])
    R = U @ D @ Vt
    scale = 1.0
    if with_scale:
        var = float((sc**2).sum() / len(src))
        if var == 0:
            raise ValueError("all commanded points coincide: scale cannot be fitted")
        scale = float(np.trace(np.diag(S) @ D) / var)
    return _finish("similarity" if with_scale else "rigid", scale * R, src, dst, scale)


def fit_affine(src: FloatArray, dst: FloatArray) -> TransformFit:
    """Least-squares affine map src -> dst: the seed's 'well-fit parallelogram'."""
    _check_pairs(src, dst, 3)
    sc = src - src.mean(axis=0)
    dc = dst - dst.mean(axis=0)
    X, _, rank, _ = np.linalg.lstsq(sc, dc, rcond=None)
    if rank < 2:
        raise ValueError("commanded points are collinear: an affine fit needs a 2-D pattern")
    A = X.T
    return _finish("affine", A, src, dst, float(math.sqrt(abs(np.linalg.det(A)))))


@dataclass(frozen=True)
class DisplacementComparison:
    """Commanded vs measured displacements (um) after each fit."""

    commanded_um: FloatArray
    measured_um: FloatArray
    rigid: TransformFit
    similarity: TransformFit
    affine: TransformFit


def compare_displacements(commanded_um: FloatArray, measured_um: FloatArray) -> DisplacementComparison:
    """Fit rigid, similarity and affine transforms from commanded to measured displacements."""
    c = np.asarray(commanded_um, dtype=np.float64)
    m = np.asarray(measured_um, dtype=np.float64)
    return DisplacementComparison(c, m, fit_rigid(c, m), fit_rigid(c, m, with_scale=True), fit_affine(c, m))


@dataclass(frozen=True)
class Repeatability:
    """ISO 9283 pose repeatability of attained positions (seed eqs. 13-18), units of the input.

    ``barycentre``: (X_bar, Y_bar) or (X_bar, Y_bar, Z_bar); ``distances``: l_i; ``l_bar``: mean l_i;
    ``s_l``: sample standard deviation of l_i (N - 1); ``rp``: l_bar + 3 s_l.
    """

    barycentre: tuple[float, ...]
    distances: FloatArray
    l_bar: float
    s_l: float
    rp: float


def _rp_of(p: FloatArray) -> tuple[FloatArray, FloatArray, float, float]:
    bary = p.mean(axis=0)
    dist = np.linalg.norm(p - bary, axis=1)
    l_bar = float(dist.mean())
    s_l = float(np.sqrt(((dist - l_bar) ** 2).sum() / (len(p) - 1)))
    return bary, dist, l_bar, s_l


def repeatability(points: FloatArray) -> Repeatability:
    """RP = l_bar + 3 S_l of attained positions ``points``: (N, 2) from images, (N, 3) with a Z sensor;
    N >= 2."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] not in (2, 3) or len(p) < 2:
        raise ValueError(f"expected (N, 2) or (N, 3) attained positions with N >= 2, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("attained positions must be finite numbers")
    bary, dist, l_bar, s_l = _rp_of(p)
    return Repeatability(tuple(float(v) for v in bary), dist, l_bar, s_l, l_bar + 3.0 * s_l)


def rp_interval(
    points: FloatArray, *, level: float = 0.95, resamples: int = 2000, seed: int = 0
) -> tuple[float, float]:
    """A ``level`` interval of RP for this many cycles: percentile bootstrap over cycles (resampled with
    replacement, barycentre recomputed each time). Seeded, so the same points give the same interval."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) < 3:
        raise ValueError(f"a bootstrap interval needs at least 3 cycles, got {len(p)}")
    if not 0 < level < 1:
        raise ValueError(f"level must be between 0 and 1, got {level}")
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, len(p), size=(resamples, len(p)))
    samples = p[idx]  # (R, N, D)
    bary = samples.mean(axis=1, keepdims=True)
    dist = np.linalg.norm(samples - bary, axis=2)
    l_bar = dist.mean(axis=1)
    s_l = dist.std(axis=1, ddof=1)
    rp = l_bar + 3.0 * s_l
    lo, hi = np.quantile(rp, [(1 - level) / 2, 1 - (1 - level) / 2])
    return float(lo), float(hi)


def scale_uncertainty(commanded: FloatArray, fit: TransformFit) -> float:
    """Standard uncertainty of a similarity fit's scale, from its residuals: sigma / sqrt(sum |c - c_bar|^2)
    with sigma^2 the per-coordinate residual variance (2N - 4 degrees of freedom)."""
    c = np.asarray(commanded, dtype=np.float64)
    n = len(c)
    if n < 3:
        raise ValueError("a scale uncertainty needs at least 3 points")
    spread = float(((c - c.mean(axis=0)) ** 2).sum())
    sigma2 = float((fit.errors**2).sum()) / (2 * n - 4)
    return math.sqrt(sigma2 / spread)
