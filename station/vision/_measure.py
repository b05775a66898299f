"""The measurement core's entry point: image + parameters -> Measurement (pure: no I/O)."""

from __future__ import annotations

import numpy as np

from station.vision._edges import EDGES
from station.vision._errors import EdgeNotFoundError, GeometryError, rotated_too_far
from station.vision._geometry import centre, check_cross, square_homography, vertices
from station.vision._image import check_quality, image_bit_depth, to_gray8
from station.vision._orientation import dominant_rotation_deg
from station.vision._paper import paper_edges
from station.vision._params import MeasureParams
from station.vision._precise import precise_edges
from station.vision._result import Measurement
from station.vision._sanity import check_single_cross


def measure(
    image: object, params: MeasureParams | None = None, *, significant_bits: int | None = None
) -> Measurement:
    """Measure the crossing of the artifact's grooves in one image.

    Parameters
    ----------
    image : ndarray
        2-D uint8 (the seed's 8-bit monochrome frame), uint16, or BGR/BGRA colour; any size from 64 px.
        It is not modified.
    params : MeasureParams, optional
        Mode and parameters; default: precise mode. ``MeasureParams(mode="paper")`` is the seed's
        algorithm with Table 1's trial 7.
    significant_bits : int, optional
        Significant bits per sample recorded by the file (PNG's sBIT); ``params.bit_depth`` wins
        over it, and without either a 16-bit image's depth is read from its data's range.

    Returns
    -------
    Measurement
        Centre (px and mm), corners, lines and diagnostics.

    Raises
    ------
    MeasurementError
        A subclass naming what is wrong: InvalidImageError, ImageQualityError, EdgeNotFoundError,
        GeometryError.
    """
    p = params if params is not None else MeasureParams()
    bit_depth = image_bit_depth(image, p.bit_depth or significant_bits)
    gray = to_gray8(image, bit_depth=bit_depth)
    check_quality(gray)
    if p.mode == "paper":
        try:
            edges = paper_edges(gray, p)
        except EdgeNotFoundError as exc:
            raise _explain_rotation(gray, p.rotation_limit_deg) or exc from None
    else:
        edges = precise_edges(gray, p)
    lines = {e: edges[e].line for e in EDGES}
    corners = vertices(lines)
    rotation, widths = check_cross(lines, corners, gray.shape, max_rotation_deg=p.rotation_limit_deg)
    check_single_cross(gray, lines, corners, widths)
    H = square_homography(corners, p.groove_width_mm)
    center_mm, center_px = centre(H, p.groove_width_mm)
    return Measurement(
        center_px=center_px,
        center_mm=center_mm,
        corners_px=corners,
        lines=np.array([lines[e] for e in EDGES], dtype=np.float64),
        homography=H,
        edges=edges,
        rotation_deg=rotation,
        groove_width_px=widths,
        params=p,
        extra={"bit_depth": bit_depth},
    )


def _explain_rotation(gray: np.ndarray, max_rotation_deg: float) -> GeometryError | None:
    """A GeometryError when edges were missed because the cross is turned beyond the mode's range."""
    rotation, strength = dominant_rotation_deg(gray)
    if strength > 0.3 and abs(rotation) > max_rotation_deg:
        return rotated_too_far(rotation, max_rotation_deg)
    return None
