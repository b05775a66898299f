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

    ``barycentre``: (X_bar, Y_bar); ``distances``: l_i; ``l_bar``: mean l_i; ``s_l``: sample standard
    deviation of l_i (N - 1); ``rp``: l_bar + 3 s_l.
    """

    barycentre: tuple[float, float]
    distances: FloatArray
    l_bar: float
    s_l: float
    rp: float


def repeatability(points: FloatArray) -> Repeatability:
    """RP = l_bar + 3 S_l of attained positions ``points`` (N, 2), N >= 2."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
        raise ValueError(f"expected (N, 2) attained positions with N >= 2, got shape {p.shape}")
    bary = p.mean(axis=0)
    dist = np.linalg.norm(p - bary, axis=1)
    l_bar = float(dist.mean())
    s_l = float(np.sqrt(((dist - l_bar) ** 2).sum() / (len(p) - 1)))
    return Repeatability((float(bary[0]), float(bary[1])), dist, l_bar, s_l, l_bar + 3.0 * s_l)
