"""Stage 5: the 3x3 raw-intensity moment (seed section 3.2.4, eqs. 7-8, Figure 10).

x = sum(x I) / sum(I), y = sum(y I) / sum(I) over the 3x3 neighbourhood of each segmented pixel, with I
from the raw (unfiltered) image, as the seed does. Known limitation (accuracy.md): on an edge along pixel
rows the estimate is pulled toward the bright side by a fraction of a pixel, the same on every column,
so the line fit cannot average it out. Paper mode keeps it faithfully; precise mode replaces it.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import numpy.typing as npt

_DY, _DX = np.mgrid[-1:2, -1:2]
#: (3, 9): the 3x3 patch's sum, x moment and y moment in one product (whole numbers: exact in float64).
_MOMENTS_T = np.vstack([np.ones(9), _DX.ravel(), _DY.ravel()]).astype(np.float64)


@lru_cache(maxsize=8)
def _offsets(w: int) -> npt.NDArray[np.intp]:
    """Flat-index offsets of a 3x3 neighbourhood in an image ``w`` pixels wide (row-major)."""
    offsets = (_DY * w + _DX).ravel().astype(np.intp)
    offsets.setflags(write=False)
    return offsets


def intensity_moment(
    raw: npt.NDArray[np.uint8], points: npt.NDArray[np.intp]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]:
    """Sub-pixel positions of integer ``points`` (N, 2) ``(x, y)``.

    Returns ``(refined, valid)``: refined (N, 2) float positions, and a mask of the points that have a
    full 3x3 neighbourhood inside the image and a non-zero intensity sum (others keep their pixel
    position and are marked invalid).
    """
    h, w = raw.shape
    x = points[:, 0]
    y = points[:, 1]
    valid = (x >= 1) & (x <= w - 2) & (y >= 1) & (y <= h - 2)
    refined = points.astype(np.float64)
    if not valid.any():
        return refined, valid
    sel = np.flatnonzero(valid)
    inner = sel.size == valid.size  # the usual case: no masks needed
    xv, yv = (x, y) if inner else (x[sel], y[sel])
    patch = raw.ravel()[_offsets(w)[:, None] + (yv * w + xv)[None, :]]  # (9, N), 8 bits
    total, mx, my = _MOMENTS_T @ patch  # whole numbers: exact in float64
    ok = total > 0
    if ok.all():
        rx, ry = xv + mx / total, yv + my / total
    else:
        safe = np.where(ok, total, 1.0)
        rx, ry = np.where(ok, xv + mx / safe, xv), np.where(ok, yv + my / safe, yv)
        valid[sel[~ok]] = False
    refined[sel, 0] = rx
    refined[sel, 1] = ry
    return refined, valid
