"""Input: turn any supported array into the 8-bit monochrome image the seed works on (section 3.1)."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._errors import ImageQualityError, InvalidImageError
from station.vision._kernels import compiled

Gray8 = npt.NDArray[np.uint8]

#: Smallest image side the pipeline accepts (px): room for the TestBox and a crossing.
MIN_SIDE_PX = 64


#: Bit depths a 16-bit container is recognised as holding (cameras give 10, 12 or 14 bits).
_DEPTHS = (8, 10, 12, 14, 16)


def image_bit_depth(image: object, declared: int | None = None) -> int:
    """Significant bits per sample: 8 for 8-bit images; for 16-bit ones ``declared`` (the file's
    sBIT chunk or ``--set bit_depth``) if given, else the smallest of 8, 10, 12, 14, 16 bits that
    holds the data's largest value (10-bit data in the low bits of a 16-bit file reads as 10)."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint16 or image.size == 0:
        return 8
    if declared is not None:
        return int(declared)
    top = int(image.max())
    return next(d for d in _DEPTHS if top < 1 << d)


def to_gray8(image: object, *, bit_depth: int | None = None) -> Gray8:
    """Convert ``image`` to a C-contiguous 2-D uint8 array, explicitly.

    * 2-D uint8: used as is (not copied, not modified).
    * 16-bit (uint16): scaled by 255/(2^bits - 1) with rounding, ``bits`` = ``bit_depth`` or, if
      None, :func:`image_bit_depth` (16 for full-range data); values above 2^bits - 1 saturate.
    * colour (H, W, 3) or (H, W, 4): converted as OpenCV's BGR/BGRA (what ``cv2.imread`` gives);
      (H, W, 1) is squeezed.

    Raises
    ------
    InvalidImageError
        Not a numpy array, empty, wrong number of dimensions or channels, unsupported dtype
        (float, bool, signed), or smaller than ``MIN_SIDE_PX`` on a side.
    """
    if not isinstance(image, np.ndarray):
        raise InvalidImageError(f"image must be a numpy array, got {type(image).__name__}")
    if image.size == 0:
        raise InvalidImageError(f"image is empty (shape {image.shape})")
    arr = image
    if arr.ndim == 3:
        channels = arr.shape[2]
        if channels == 1:
            arr = arr[:, :, 0]
        elif channels not in (3, 4):
            raise InvalidImageError(f"image has {channels} channels; expected 1 (grey), 3 (BGR) or 4 (BGRA)")
    elif arr.ndim != 2:
        raise InvalidImageError(f"image must be 2-D (grey) or 3-D (colour), got shape {image.shape}")
    if arr.dtype not in (np.uint8, np.uint16):
        raise InvalidImageError(
            f"image dtype {arr.dtype} is not supported; convert to uint8 or uint16 (grey levels)"
        )
    if arr.dtype == np.uint16 or arr.ndim == 3:
        bits = image_bit_depth(arr, bit_depth) if arr.dtype == np.uint16 else 8
        arr = _gray8_in_bands(arr, bits)
    h, w = arr.shape[:2]
    if h < MIN_SIDE_PX or w < MIN_SIDE_PX:
        raise InvalidImageError(
            f"image is {w}x{h} px; at least {MIN_SIDE_PX}x{MIN_SIDE_PX} px are needed "
            "(the nominal frame is 640x480)"
        )
    return np.ascontiguousarray(arr)


BAND_SAMPLES = 1 << 20
"""Samples converted at a time by :func:`to_gray8`: a band's float copy, not the whole frame's."""


def _gray8_in_bands(arr: npt.NDArray[np.uint8] | npt.NDArray[np.uint16], bits: int) -> Gray8:
    """16-bit scaled to 8 (by 255/(2^bits - 1), rounded; saturating above 2^bits - 1) and colour
    converted as BGR/BGRA, one band of rows at a time. Every output pixel depends on its own input
    pixel only, so the bands give the whole frame's result exactly; a 45 Mpx 16-bit colour frame then
    needs a few MB of temporaries instead of two float32 copies of itself (1 GB)."""
    height, width = arr.shape[:2]
    out = np.empty((height, width), np.uint8)
    scale = 255.0 / ((1 << bits) - 1)
    code = None
    if arr.ndim == 3:
        code = cv2.COLOR_BGR2GRAY if arr.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
    step = max(1, BAND_SAMPLES // max(1, arr[0].size))
    for top in range(0, height, step):
        band: npt.NDArray[Any] = arr[top : top + step]
        if band.dtype == np.uint16:
            scaled = np.rint(band.astype(np.float32) * scale)
            band = (scaled if bits == 16 else np.minimum(scaled, 255.0)).astype(np.uint8)
        if code is not None:
            band = cv2.cvtColor(np.ascontiguousarray(band), code)
        out[top : top + step] = band
    return out


def check_quality(gray: Gray8) -> None:
    """Reject frames no method can measure, with the likely cause.

    Raises
    ------
    ImageQualityError
        Blank (grey levels span under 10 DN between the 1st and 99th percentiles) or saturated
        (over half the pixels at 255).
    """
    ck = compiled()
    if ck is not None:  # the same statistics in one pass (``_kernels``)
        lo, hi, saturated = ck.quality(np.ascontiguousarray(gray))
    else:
        sample = gray[::4, ::4]  # one pixel in 16 decides as well (19,200 of a 640x480 frame), 6x faster
        hist = cv2.calcHist([np.ascontiguousarray(sample)], [0], None, [256], [0, 256]).ravel()
        cdf = np.cumsum(hist) / sample.size
        lo = int(np.searchsorted(cdf, 0.01))
        hi = int(np.searchsorted(cdf, 0.99))
        saturated = float(hist[255] / sample.size)
    if saturated > 0.5:
        raise ImageQualityError(
            f"image is saturated: {saturated:.0%} of pixels at 255; reduce exposure, gain or illumination"
        )
    if hi - lo < 10:
        raise ImageQualityError(
            f"image is blank: grey levels span only {lo}-{hi}; check illumination, lens cap and focus"
        )
