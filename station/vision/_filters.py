"""Stage 1, noise filtering (seed section 3.2.1, eqs. 1-3)."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

Float32Image = npt.NDArray[np.float32]


def gauss_kernel_7x7(sigma: float) -> npt.NDArray[np.float64]:
    """The seed's 7x7 Gaussian mask, eq. 2, ``g[i, j] = c exp(-(i^2 + j^2) / (2 sigma^2))``, normalised.

    The mask printed as eq. 3 is malformed (6 rows, not symmetric); its densest row (2 4 8 16 8 4 2)
    halves per pixel, i.e. sigma = 1/sqrt(2 ln 2) = 0.85 px, the default (the seed paper: see README).
    """
    i = np.arange(-3, 4, dtype=np.float64)
    g1 = np.exp(-(i**2) / (2.0 * sigma**2))
    g = np.outer(g1, g1)
    return g / g.sum()


def apply_filter(gray: npt.NDArray[np.uint8], kind: str, *, gauss_sigma: float) -> Float32Image:
    """Filter an 8-bit image; returns float32 (a new array; ``gray`` is not modified).

    ``none``: the image as float; ``mean``: the 3x3 all-ones mask of eq. 1 (normalised: the threshold
    of section 3.2.3 is relative, so scale does not matter); ``gauss``: the 7x7 mask of eq. 2.
    Borders replicate the edge pixels.
    """
    img = gray.astype(np.float32)
    if kind == "none":
        return img
    if kind == "mean":
        return np.asarray(cv2.blur(img, (3, 3), borderType=cv2.BORDER_REPLICATE), np.float32)
    if kind == "gauss":
        g1 = np.exp(-(np.arange(-3, 4) ** 2) / (2.0 * gauss_sigma**2)).astype(np.float32)
        g1 /= g1.sum()
        return np.asarray(
            cv2.sepFilter2D(img, cv2.CV_32F, g1, g1, borderType=cv2.BORDER_REPLICATE), np.float32
        )
    raise ValueError(f"filter {kind!r} is not one of none, mean, gauss")
