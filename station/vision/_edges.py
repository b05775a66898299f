"""Stages 2-3: the four directional Prewitt operators and the threshold (seed 3.2.2-3.2.3, eq. 4).

Edge names: the horizontal groove is bounded by the ``top`` edge (bright land above, dark groove below)
and the ``bottom`` edge (dark above, bright below: eq. 4's own operator); the vertical groove by the
``left`` edge (bright left, dark right) and the ``right`` edge (dark left, bright right).
"""

from __future__ import annotations

from typing import Final, Literal

import cv2
import numpy as np
import numpy.typing as npt

Edge = Literal["top", "bottom", "left", "right"]
EDGES: Final[tuple[Edge, ...]] = ("top", "bottom", "left", "right")
Float32Image = npt.NDArray[np.float32]

#: Eq. 4 (correlation: response = sum of the row below - sum of the row above).
PREWITT_DOWN: Final = np.array([[-1, -1, -1], [0, 0, 0], [1, 1, 1]], dtype=np.float32)
PREWITT_RIGHT: Final = np.ascontiguousarray(PREWITT_DOWN.T)
#: Eq. 4 as the outer product of a difference across the edge and a sum along it.
_DIFF3: Final = np.array([-1.0, 0.0, 1.0], np.float32)
_SUM3: Final = np.ones(3, np.float32)


def operator_responses(filtered: Float32Image | npt.NDArray[np.uint8]) -> tuple[Float32Image, Float32Image]:
    """Eq. 4 and its transpose, both polarities: (gy, gx). ``bottom`` is max(gy, 0), ``top``
    max(-gy, 0), ``right`` max(gx, 0), ``left`` max(-gx, 0). An 8-bit image gives the same values as
    its float32 copy (sums of whole numbers are exact)."""
    if filtered.dtype == np.uint8:
        # the operators are separable (a difference across, a 3-sum along): 4x faster than the 3x3
        # correlation, and the same whole numbers (exact in float32 in any order of summation)
        gy = cv2.sepFilter2D(filtered, cv2.CV_32F, _SUM3, _DIFF3, borderType=cv2.BORDER_REPLICATE)
        gx = cv2.sepFilter2D(filtered, cv2.CV_32F, _DIFF3, _SUM3, borderType=cv2.BORDER_REPLICATE)
    else:
        gy = cv2.filter2D(filtered, cv2.CV_32F, PREWITT_DOWN, borderType=cv2.BORDER_REPLICATE)
        gx = cv2.filter2D(filtered, cv2.CV_32F, PREWITT_RIGHT, borderType=cv2.BORDER_REPLICATE)
    return np.asarray(gy, np.float32), np.asarray(gx, np.float32)


def threshold_level(peak: float, fraction: float) -> float:
    """The value above which a response is kept (section 3.2.3): just below ``fraction * peak`` in
    float32, so that a value equal to it is kept."""
    return float(np.nextafter(np.float32(fraction * peak), np.float32(-np.inf)))


def directional_responses(filtered: Float32Image) -> dict[Edge, Float32Image]:
    """The four operators' responses, each keeping only its own polarity (negative values -> 0).

    ``bottom`` is eq. 4 (dark above, bright below); ``top`` its negation; ``right`` is eq. 4
    transposed (dark left, bright right); ``left`` its negation. Shapes equal ``filtered``'s.
    """
    gy, gx = operator_responses(filtered)
    return {
        "top": np.maximum(-gy, 0.0),
        "bottom": np.maximum(gy, 0.0),
        "left": np.maximum(-gx, 0.0),
        "right": np.maximum(gx, 0.0),
    }


def apply_threshold(response: Float32Image, fraction: float) -> Float32Image:
    """Zero every value below ``fraction`` of the maximum (section 3.2.3); returns a new array."""
    peak = float(response.max())
    if peak <= 0.0:
        return np.zeros_like(response)
    # THRESH_TOZERO keeps values strictly above the threshold: step just below it to keep equality
    level = threshold_level(peak, fraction)
    _, out = cv2.threshold(response, level, 0.0, cv2.THRESH_TOZERO)
    return np.asarray(out, np.float32)
