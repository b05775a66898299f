"""The ruler position's noise limit in closed form: the Cramer-Rao bound of the graduations' edges.

A graduation line is a bar with two edges across the ruler. Seen by a pixel, an edge blurred by a
Gaussian of ``blur_sigma_px`` and averaged over the pixel's box is a step whose derivative along the
ruler is close to a Gaussian of ``sigma_e = sqrt(blur^2 + 1/12)`` px (the box's variance added); a row
of pixels crossing it carries, about the edge's place, the Fisher information
``C^2 / noise^2 * sum g'(x)^2 = C^2 / (2 sqrt(pi) sigma_e noise^2)`` (``C`` the contrast in DN, the sum
over the row close to its integral once ``sigma_e`` exceeds half a pixel). Every edge of every line in
view adds its rows: the bound of the grating's position along the ruler is one over the square root
of the total. This is the bound with everything else known (the frame's scale, direction and
perspective, the grey levels): those and the position's extrapolation to a pixel away from the
pattern can only raise it, the code track's cells, whose edges also cross the ruler, lower it.
``bench/ruler_bench.py`` computes the full bound numerically from the twin's rendering over the
pose and grey levels; this one says where the number comes from.
"""

from __future__ import annotations

import math

from station.vision._ruler_spec import RulerSpec

#: The variance of a pixel's box along one axis (px^2).
PIXEL_BOX_VARIANCE = 1.0 / 12.0


def edge_information(contrast_dn: float, noise_dn: float, blur_sigma_px: float) -> float:
    """Fisher information (1 / px^2) about an edge's place from one row of pixels crossing it."""
    if not (contrast_dn > 0 and noise_dn > 0 and blur_sigma_px >= 0):
        raise ValueError("edge_information: contrast and noise must be > 0, the blur >= 0")
    sigma_e = math.sqrt(blur_sigma_px**2 + PIXEL_BOX_VARIANCE)
    return contrast_dn**2 / (2.0 * math.sqrt(math.pi) * sigma_e * noise_dn**2)


def graduation_position_bound_px(
    *,
    contrast_dn: float,
    noise_dn: float,
    blur_sigma_px: float,
    graduations: float,
    line_rows_px: float,
) -> float:
    """The Cramer-Rao standard deviation (px) of the graduations' position along the ruler.

    Parameters
    ----------
    contrast_dn : float
        Grey-level difference between the ground and the marks, DN.
    noise_dn : float
        Standard deviation of one pixel's noise, DN (read, shot and quantisation combined).
    blur_sigma_px : float
        Standard deviation of the optics' Gaussian blur, px.
    graduations : float
        Graduation lines in view (two edges each).
    line_rows_px : float
        Rows of pixels along each line that cross its edges: the lines' length in view, px.

    Returns
    -------
    float
        One standard deviation, px, with every other parameter known (module docstring).
    """
    if not (graduations > 0 and line_rows_px > 0):
        raise ValueError("graduation_position_bound_px: graduations and line rows must be > 0")
    total = 2.0 * graduations * line_rows_px * edge_information(contrast_dn, noise_dn, blur_sigma_px)
    return 1.0 / math.sqrt(total)


def ruler_view_bound_px(
    spec: RulerSpec,
    *,
    px_per_mm: float,
    graduated_mm: float,
    contrast_dn: float,
    noise_dn: float,
    blur_sigma_px: float,
) -> float:
    """``graduation_position_bound_px`` for a view of ``spec`` showing ``graduated_mm`` of it, whole
    across (both parts of the lines), at ``px_per_mm``."""
    lines_mm = sum(hi - lo for lo, hi in spec.line_segments_mm)
    return graduation_position_bound_px(
        contrast_dn=contrast_dn,
        noise_dn=noise_dn,
        blur_sigma_px=blur_sigma_px,
        graduations=graduated_mm / spec.pitch_mm,
        line_rows_px=lines_mm * px_per_mm,
    )
