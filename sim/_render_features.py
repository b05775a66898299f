"""Surface features fixed to the artifact (streaks, scratches, glints) and to the camera (vignetting).

Every artifact feature is drawn once from the artifact's ``texture_seed`` in artifact coordinates
(mm) over a square of half-size ``FEATURE_HALF_EXTENT_MM`` around the crossing, and mapped into each
image through the pose's homography, so it moves with the artifact. Catalogues are drawn at the
largest density a preset may ask for; a preset takes the first ``density * area`` entries, so a
sparser preset shows a subset of the same glints and scratches.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import numpy.typing as npt
from scipy.special import ndtr

from sim._render_geometry import Float32Array, FloatArray, box_step, cutoff_px
from sim.presets import MAX_GLINTS_PER_MM, MAX_SCRATCHES_PER_MM2, NoisePreset

__all__ = [
    "FEATURE_HALF_EXTENT_MM",
    "add_blobs",
    "artifact_rng",
    "glint_image",
    "local_scale",
    "project_points",
    "scratch_image",
    "streak_texture",
    "vignetting_map",
]

FEATURE_HALF_EXTENT_MM = 12.0
"""Half-size of the textured square around the crossing, mm (covers the frame wherever the crossing is)."""

_STREAK_STEP_MM = 0.001
_STREAK_HALF_LENGTH_MM = FEATURE_HALF_EXTENT_MM * 1.5
_STREAK_PERIODS_MM = (0.008, 0.4)  # finest and coarsest streak period, mm


def artifact_rng(texture_seed: int, stream: int) -> np.random.Generator:
    """The artifact's generator for one kind of feature (``stream``: 1 streaks, 2 glints, 3 scratches,
    4 flecks, 5 specks), so that each kind's catalogue is independent of the others'."""
    return np.random.default_rng([int(texture_seed), 0x5EED, stream])


# --------------------------------------------------------------------------- streaks


@lru_cache(maxsize=8)
def _streak_spectrum(texture_seed: int) -> tuple[float, npt.NDArray[np.complex128], FloatArray]:
    """Angle of the streaks (rad, artifact frame), rfft of the unit-RMS profile, frequencies (1/mm)."""
    rng = artifact_rng(texture_seed, 1)
    angle = float(rng.uniform(0.0, np.pi))
    n = round(2 * _STREAK_HALF_LENGTH_MM / _STREAK_STEP_MM) + 1
    spectrum = np.fft.rfft(rng.standard_normal(n))
    freq = np.asarray(np.fft.rfftfreq(n, _STREAK_STEP_MM), dtype=np.float64)
    lo, hi = 1.0 / _STREAK_PERIODS_MM[1], 1.0 / _STREAK_PERIODS_MM[0]
    band = (freq >= lo) & (freq <= hi)
    spectrum = np.where(band, spectrum / np.sqrt(np.maximum(freq, lo)), 0.0)  # pink within the band
    profile = np.fft.irfft(spectrum, n)
    spectrum = spectrum / float(np.sqrt(np.mean(profile**2)))
    spectrum.setflags(write=False)
    return angle, spectrum, freq


def streak_texture(
    inv_h: FloatArray, shape: tuple[int, int], *, texture_seed: int, sigma_px: float, px_per_mm: float
) -> Float32Array:
    """Machining streaks: a unit-RMS (before blur) profile across parallel lines on the artifact.

    Parameters
    ----------
    inv_h : numpy.ndarray, shape (3, 3)
        Image px -> artifact mm homography.
    shape : (int, int)
        Image shape ``(height, width)``.
    texture_seed : int
        The artifact's seed (streak direction and profile).
    sigma_px : float
        Optical blur, px: the profile is low-pass filtered by the blur and the pixel footprint.
    px_per_mm : float
        Image scale at the artifact origin, px/mm (the filter uses one scale for the whole image).

    Returns
    -------
    numpy.ndarray, shape ``shape``, float32
        Texture value per pixel (dimensionless; multiply by the preset's RMS in DN).
    """
    angle, spectrum, freq = _streak_spectrum(texture_seed)
    normal = np.array([-np.sin(angle), np.cos(angle), 0.0])  # s = -u sin + v cos, across the streaks
    # Footprint of a pixel on s: the image direction of grad s gives the trapezoid widths (mm).
    row = normal @ inv_h  # s(x, y) = (row . p) / (inv_h[2] . p), p = (x, y, 1)
    g = np.abs(row[:2]) / max(float(np.hypot(*row[:2])), 1e-300)  # direction of grad s (no tilt)
    sigma_mm = sigma_px / px_per_mm
    filt = np.exp(-2.0 * (np.pi * sigma_mm * freq) ** 2)
    filt = filt * np.sinc(g[0] * freq / px_per_mm) * np.sinc(g[1] * freq / px_per_mm)
    profile = np.fft.irfft(spectrum * filt, round(2 * _STREAK_HALF_LENGTH_MM / _STREAK_STEP_MM) + 1)
    # float32 is ample here: indices up to 36000 with ~0.003 of a 1 um step of rounding.
    xs = np.arange(shape[1], dtype=np.float32)
    ys = np.arange(shape[0], dtype=np.float32)
    row32, den32 = row.astype(np.float32), inv_h[2].astype(np.float32)
    num = row32[0] * xs[None, :] + (row32[1] * ys[:, None] + row32[2])
    den = den32[0] * xs[None, :] + (den32[1] * ys[:, None] + den32[2])
    idx = num / den
    idx += np.float32(_STREAK_HALF_LENGTH_MM)
    idx *= np.float32(1.0 / _STREAK_STEP_MM)
    # below the last sample, in float32 (where size - 1.001 rounds up to size - 1 past 16384 samples):
    # a point beyond the profile's half length takes its end value instead of indexing past it
    np.clip(idx, 0.0, np.nextafter(np.float32(profile.size - 1), np.float32(0.0)), out=idx)
    i0 = idx.astype(np.intp)
    frac = idx - i0
    p32 = profile.astype(np.float32)
    lower = p32[i0]
    return np.asarray(lower + (p32[i0 + 1] - lower) * frac)


# --------------------------------------------------------------------------- glints and scratches


@dataclass(frozen=True)
class _Catalogue:
    """Unit random variates of the artifact's glints and scratches (scaled by the preset)."""

    glints: FloatArray  # (2, n, 4): per groove (horizontal, vertical): along, across, size, peak in [0,1)
    scratches: FloatArray  # (m, 6): u, v (mm), angle (rad), length, width, depth in [0, 1)


@lru_cache(maxsize=8)
def _catalogue(texture_seed: int) -> _Catalogue:
    n = int(np.ceil(MAX_GLINTS_PER_MM * 2 * FEATURE_HALF_EXTENT_MM))
    glints = artifact_rng(texture_seed, 2).random((2, n, 4))
    m = int(np.ceil(MAX_SCRATCHES_PER_MM2 * (2 * FEATURE_HALF_EXTENT_MM) ** 2))
    raw = artifact_rng(texture_seed, 3).random((m, 6))
    scratches = raw.copy()
    scratches[:, :2] = (2.0 * raw[:, :2] - 1.0) * FEATURE_HALF_EXTENT_MM
    scratches[:, 2] = raw[:, 2] * np.pi
    for arr in (glints, scratches):
        arr.setflags(write=False)
    return _Catalogue(glints, scratches)


def project_points(h: FloatArray, uv: FloatArray) -> FloatArray:
    """Artifact mm (n, 2) -> image px (n, 2) through ``h``."""
    p = np.column_stack([uv, np.ones(len(uv))]) @ h.T
    return np.asarray(p[:, :2] / p[:, 2:3])


def local_scale(h: FloatArray, uv: FloatArray) -> FloatArray:
    """sqrt(|det J|) of the homography at artifact points (n, 2): local px per mm."""
    w = uv @ h[2, :2] + h[2, 2]
    x = (uv @ h[0, :2] + h[0, 2]) / w
    y = (uv @ h[1, :2] + h[1, 2]) / w
    j11, j12 = (h[0, 0] - x * h[2, 0]) / w, (h[0, 1] - x * h[2, 1]) / w
    j21, j22 = (h[1, 0] - y * h[2, 0]) / w, (h[1, 1] - y * h[2, 1]) / w
    return np.asarray(np.sqrt(np.abs(j11 * j22 - j12 * j21)))


def _window(center: FloatArray, half: float, shape: tuple[int, int]) -> tuple[slice, slice] | None:
    """Row/column slices of the pixels within ``half`` px of ``center`` (x, y), or None if outside."""
    x0, x1 = max(int(np.floor(center[0] - half)), 0), min(int(np.ceil(center[0] + half)) + 1, shape[1])
    y0, y1 = max(int(np.floor(center[1] - half)), 0), min(int(np.ceil(center[1] + half)) + 1, shape[0])
    if x0 >= x1 or y0 >= y1:
        return None
    return slice(y0, y1), slice(x0, x1)


def glint_image(
    h: FloatArray, shape: tuple[int, int], *, texture_seed: int, groove_width_mm: float, preset: NoisePreset
) -> Float32Array:
    """Specular glints on the paint: Gaussian blobs, blurred, DN above the paint level.

    Parameters
    ----------
    h : numpy.ndarray, shape (3, 3)
        Artifact mm -> image px homography.
    shape : (int, int)
        Image shape.
    texture_seed : int
        The artifact's seed.
    groove_width_mm : float
        True groove width (glints lie inside the grooves, ``preset.glint_wall_margin_mm`` from walls).
    preset : NoisePreset
        Density, sizes, peaks and blur.

    Returns
    -------
    numpy.ndarray, shape ``shape``, float32
        Glint brightness, DN (to be weighted by the paint coverage).
    """
    out = np.zeros(shape, dtype=np.float32)
    count = round(preset.glints_per_mm * 2 * FEATURE_HALF_EXTENT_MM)
    half_across = max(groove_width_mm / 2 - preset.glint_wall_margin_mm, 0.0)
    if count == 0:
        return out
    cat = _catalogue(texture_seed).glints[:, :count, :]
    along = (2.0 * cat[..., 0] - 1.0) * FEATURE_HALF_EXTENT_MM
    across = (2.0 * cat[..., 1] - 1.0) * half_across
    uv = np.concatenate([np.column_stack([along[0], across[0]]), np.column_stack([across[1], along[1]])])
    sizes = np.concatenate(cat[..., 2])
    peaks = np.concatenate(cat[..., 3])
    sigma_mm = preset.glint_sigma_min_mm + sizes * (preset.glint_sigma_max_mm - preset.glint_sigma_min_mm)
    peak_dn = preset.glint_peak_min_dn + peaks * (preset.glint_peak_max_dn - preset.glint_peak_min_dn)
    xy = project_points(h, uv)
    sigma_g = sigma_mm * local_scale(h, uv)
    # Blur and pixel box (variance 1/12 per axis) widen the blob and keep its integral.
    sigma_e = np.sqrt(sigma_g**2 + preset.blur_sigma_px**2 + 1.0 / 12.0)
    amp = peak_dn * (sigma_g / sigma_e) ** 2
    add_blobs(out, xy, sigma_e, amp)
    return out


def add_blobs(out: Float32Array, xy: FloatArray, sigma_px: FloatArray, amplitude: FloatArray) -> None:
    """Add Gaussian blobs to ``out`` in place: centres ``xy`` (n, 2) px, radii and peaks (n,), each
    drawn within 4.5 radii of its centre (blobs wholly outside the frame cost nothing)."""
    shape = (out.shape[0], out.shape[1])
    for (cx, cy), se, a in zip(xy, sigma_px, amplitude, strict=True):
        win = _window(np.array([cx, cy]), 4.5 * se, shape)
        if win is None:
            continue
        ys = np.arange(win[0].start, win[0].stop, dtype=np.float64)[:, None] - cy
        xs = np.arange(win[1].start, win[1].stop, dtype=np.float64)[None, :] - cx
        out[win] += (a * np.exp(-(xs * xs + ys * ys) / (2.0 * se * se))).astype(np.float32)


def scratch_image(
    h: FloatArray, shape: tuple[int, int], *, texture_seed: int, preset: NoisePreset
) -> Float32Array:
    """Scratches on the lands: thin dark lines, exactly area-integrated across, tapered at the ends.

    Parameters
    ----------
    h : numpy.ndarray, shape (3, 3)
        Artifact mm -> image px homography.
    shape : (int, int)
        Image shape.
    texture_seed : int
        The artifact's seed.
    preset : NoisePreset
        Density, sizes, depth and blur.

    Returns
    -------
    numpy.ndarray, shape ``shape``, float32
        Darkening, DN (positive; to be weighted by the land coverage and subtracted).
    """
    out = np.zeros(shape, dtype=np.float32)
    count = round(preset.scratches_per_mm2 * (2 * FEATURE_HALF_EXTENT_MM) ** 2)
    if count == 0:
        return out
    cat = _catalogue(texture_seed).scratches[:count]
    sigma = preset.blur_sigma_px
    half_len = 0.5 * preset.scratch_length_max_mm * (0.2 + 0.8 * cat[:, 3])
    direction = np.column_stack([np.cos(cat[:, 2]), np.sin(cat[:, 2])])
    starts = project_points(h, cat[:, :2] - half_len[:, None] * direction)
    stops = project_points(h, cat[:, :2] + half_len[:, None] * direction)
    scale = local_scale(h, cat[:, :2])
    half_w = 0.5 * preset.scratch_width_max_mm * (0.3 + 0.7 * cat[:, 4]) * scale
    depth = preset.scratch_depth_dn * (0.3 + 0.7 * cat[:, 5])
    reach = half_w + cutoff_px(sigma)
    lo = np.minimum(starts, stops) - reach[:, None]
    hi = np.maximum(starts, stops) + reach[:, None]
    visible = (hi[:, 0] >= 0) & (hi[:, 1] >= 0) & (lo[:, 0] <= shape[1] - 1) & (lo[:, 1] <= shape[0] - 1)
    taper_sigma = max(sigma, 1.0)
    for k in np.flatnonzero(visible):
        axis = stops[k] - starts[k]
        length_px = float(np.hypot(*axis))
        if length_px == 0.0:
            continue
        axis /= length_px
        normal = np.array([-axis[1], axis[0]])
        band_px = _segment_band(starts[k], axis, length_px, float(reach[k]), shape)
        if band_px is None:
            continue
        rows, cols = band_px
        rel_x, rel_y = cols - starts[k][0], rows - starts[k][1]
        across = rel_x * normal[0] + rel_y * normal[1]
        along = rel_x * axis[0] + rel_y * axis[1]
        ca, sa = abs(normal[0]), abs(normal[1])
        profile = box_step(across + half_w[k], ca, sa, sigma) - box_step(across - half_w[k], ca, sa, sigma)
        taper = ndtr(along / taper_sigma) * ndtr((length_px - along) / taper_sigma)
        out[rows, cols] += (depth[k] * profile * taper).astype(np.float32)
    return out


def _segment_band(
    start: FloatArray, axis: FloatArray, length_px: float, reach: float, shape: tuple[int, int]
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]] | None:
    """Pixels (rows, cols) within ``reach`` px of the segment's line and of its span, or None.

    Scans columns for a segment closer to horizontal (rows for one closer to vertical), taking the
    few pixels per scan line that can be within reach, so the cost follows the segment, not its box.
    """
    steep = abs(axis[1]) > abs(axis[0])
    k_along, k_across = (1, 0) if steep else (0, 1)  # coordinate scanned, coordinate across
    n_along, n_across = (shape[0], shape[1]) if steep else (shape[1], shape[0])
    ends = (start[k_along], start[k_along] + length_px * axis[k_along])
    lo = max(int(np.floor(min(ends) - reach)), 0)
    hi = min(int(np.ceil(max(ends) + reach)) + 1, n_along)
    if lo >= hi:
        return None
    scan = np.arange(lo, hi)
    slope = axis[k_across] / axis[k_along]
    centre = start[k_across] + (scan - start[k_along]) * slope
    half = reach / abs(axis[k_along])
    first = np.floor(centre - half).astype(np.intp)
    across = first[None, :] + np.arange(int(np.ceil(2 * half)) + 2)[:, None]
    along = np.broadcast_to(scan, across.shape)
    inside = (across >= 0) & (across < n_across)
    if not inside.any():
        return None
    a_idx, s_idx = across[inside], along[inside]
    return (s_idx, a_idx) if steep else (a_idx, s_idx)


# --------------------------------------------------------------------------- vignetting


@lru_cache(maxsize=8)
def vignetting_map(shape: tuple[int, int], strength: float) -> Float32Array:
    """Radial brightness factor ``1 - strength * (r / r_corner)^2`` about the image centre, float32."""
    height, width = shape
    ys = (np.arange(height) - (height - 1) / 2.0)[:, None]
    xs = (np.arange(width) - (width - 1) / 2.0)[None, :]
    r2 = (xs * xs + ys * ys) / (((width - 1) / 2.0) ** 2 + ((height - 1) / 2.0) ** 2)
    out = (1.0 - strength * r2).astype(np.float32)
    out.setflags(write=False)
    return out
