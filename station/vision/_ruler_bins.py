"""The ruler measurement's one pass over the pixels: each pixel summed into a bin of its strip.

A strip is a band ``t_lo <= t < t_hi`` of the ruler's frame (periods), cut along ``s`` into bins of
``1 / per_period`` periods from ``s_lo``. Every pixel whose ``(s, t)`` falls in a bin adds to that
bin's count, intensity sum, ``s`` and ``t`` sums and second moments; everything after this pass
works on the bins (a few thousand numbers, not the 300,000 pixels). The compiled kernel
(``_ckernels.ruler_bins``) does the same arithmetic in the same order; this module is the reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.vision._kernels import compiled
from station.vision._ruler_frame import RulerFrame

FloatArray = npt.NDArray[np.float64]

#: Per bin: count, sum of I, sum of s, sum of t, sum of s^2, sum of s*t.
BIN_FIELDS = ("n", "i", "s", "t", "ss", "st")


@dataclass(frozen=True)
class Strips:
    """Strips sorted by ``t``, not overlapping: ``(t_lo, t_hi, s_lo, per_period, bins)`` per row."""

    table: FloatArray

    def __post_init__(self) -> None:
        t = self.table
        if t.ndim != 2 or t.shape[1] != 5 or len(t) == 0:
            raise ValueError("strips: expected a non-empty (k, 5) table")
        if np.any(t[:, 1] <= t[:, 0]) or np.any(t[1:, 0] < t[:-1, 1]) or np.any(t[:, 3] <= 0):
            raise ValueError("strips must be sorted by t, not overlapping, with positive bin sizes")

    @property
    def offsets(self) -> npt.NDArray[np.int64]:
        """Index of each strip's first bin in the output (and the total at the end)."""
        return np.concatenate([[0], np.cumsum(self.table[:, 4].astype(np.int64))])


def fold(
    gray: npt.NDArray[np.uint8],
    frame: RulerFrame,
    strips: Strips,
    coords: tuple[FloatArray, FloatArray] | None = None,
    *,
    step: int = 1,
) -> FloatArray:
    """Sum every pixel into its strip's bin.

    Parameters
    ----------
    gray : ndarray, (H, W) uint8
        The image.
    frame : RulerFrame
        Image -> ruler (periods).
    strips : Strips
        The strips.
    coords : (ndarray, ndarray), optional
        Undistorted ``(x, y)`` of every pixel, each (H, W) float64 (a camera model); default the pixel
        centres.
    step : int
        Every ``step``-th pixel of every ``step``-th row only (a quicker, coarser pass).

    Returns
    -------
    ndarray, (total bins, 6) float64
        Per bin the sums named by ``BIN_FIELDS``.
    """
    offsets = strips.offsets
    out = np.zeros((int(offsets[-1]), len(BIN_FIELDS)))
    ck = compiled()
    m = np.ascontiguousarray(frame.matrix, dtype=np.float64).ravel()
    table = np.ascontiguousarray(strips.table, dtype=np.float64)
    if ck is not None:
        cx, cy = (None, None) if coords is None else (np.ascontiguousarray(c, np.float64) for c in coords)
        ck.ruler_bins(np.ascontiguousarray(gray), cx, cy, m, table, step, out)
        return out
    h, w = gray.shape
    if coords is None:
        xs = np.broadcast_to(
            np.arange(0, w, step, dtype=np.float64)[None, :], (len(range(0, h, step)), len(range(0, w, step)))
        )
        ys = np.broadcast_to(np.arange(0, h, step, dtype=np.float64)[:, None], xs.shape)
    else:
        xs, ys = coords[0][::step, ::step], coords[1][::step, ::step]
    gray = gray[::step, ::step]
    inv = 1.0 / (m[6] * xs + m[7] * ys + m[8])
    s = (m[0] * xs + m[1] * ys + m[2]) * inv
    t = (m[3] * xs + m[4] * ys + m[5]) * inv
    k = np.searchsorted(table[:, 0], t, side="right") - 1
    kk = np.maximum(k, 0)
    valid = (k >= 0) & (t < table[kk, 1])
    b = (s - table[kk, 2]) * table[kk, 3]
    valid &= (b >= 0) & (b < table[kk, 4])
    index = offsets[kk[valid]] + b[valid].astype(np.int64)
    sv, tv = s[valid], t[valid]
    size = len(out)
    out[:, 0] = np.bincount(index, minlength=size)
    out[:, 1] = np.bincount(index, gray[valid].astype(np.float64), minlength=size)
    out[:, 2] = np.bincount(index, sv, minlength=size)
    out[:, 3] = np.bincount(index, tv, minlength=size)
    out[:, 4] = np.bincount(index, sv * sv, minlength=size)
    out[:, 5] = np.bincount(index, sv * tv, minlength=size)
    return out
