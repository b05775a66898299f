"""Flecks and specks: chips in the grooves' paint with a glint on each, and bright dust on the artifact.

A worn artifact loses its black paint in small chips: bare metal shows through, nearly as bright as
a land, and a chip's broken edge catches the light in a glint that saturates the pixel. Dust lying on
the artifact (lands and grooves alike) shows as bright specks. Both are fixed to the artifact like
the glints and scratches of ``sim._render_features``: drawn once from the artifact's
``texture_seed`` (streams 4 and 5, so the older features' catalogues are untouched) at the largest
density a preset may ask for, a preset taking the first ``density * area`` entries, and mapped into
each image through the pose's homography. A preset with neither (``nominal``, ``hard``) renders
exactly what it rendered before they existed.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from sim._render_features import (
    FEATURE_HALF_EXTENT_MM,
    add_blobs,
    artifact_rng,
    local_scale,
    project_points,
)
from sim._render_geometry import Float32Array, FloatArray
from sim.presets import MAX_FLECKS_PER_MM, MAX_SPECKS_PER_MM2, NoisePreset

__all__ = ["fleck_image", "fleck_points", "speck_image", "speck_points"]

#: Chips in one cluster (a damaged spot of the paint).
FLECKS_PER_CLUSTER = 6
#: A chip's glint has this fraction of the chip's radius.
GLINT_TO_FLECK_RADIUS = 1.0 / 3.0


@dataclass(frozen=True)
class _Catalogue:
    """Unit random variates of the artifact's flecks and specks (scaled by the preset)."""

    flecks: FloatArray  # (2, n, 5): per groove: along, across, size, peak, glint peak in [0, 1)
    specks: FloatArray  # (m, 4): u, v (mm), size, peak in [0, 1)


@lru_cache(maxsize=8)
def _catalogue(texture_seed: int) -> _Catalogue:
    n = int(np.ceil(MAX_FLECKS_PER_MM * 2 * FEATURE_HALF_EXTENT_MM))
    flecks = artifact_rng(texture_seed, 4).random((2, n, 5))
    m = int(np.ceil(MAX_SPECKS_PER_MM2 * (2 * FEATURE_HALF_EXTENT_MM) ** 2))
    raw = artifact_rng(texture_seed, 5).random((m, 4))
    specks = raw.copy()
    specks[:, :2] = (2.0 * raw[:, :2] - 1.0) * FEATURE_HALF_EXTENT_MM
    for arr in (flecks, specks):
        arr.setflags(write=False)
    return _Catalogue(flecks, specks)


def _blurred(
    h: FloatArray, uv: FloatArray, sigma_mm: FloatArray, peak_dn: FloatArray, blur_px: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Image centres (n, 2), radii and peaks (n,) of Gaussian blobs on the artifact after the optical
    blur and the pixel box (variance 1/12 per axis), which widen a blob and keep its integral."""
    xy = project_points(h, uv)
    sigma_g = sigma_mm * local_scale(h, uv)
    sigma_e = np.sqrt(sigma_g**2 + blur_px**2 + 1.0 / 12.0)
    return xy, sigma_e, peak_dn * (sigma_g / sigma_e) ** 2


def _flecks(
    texture_seed: int, groove_width_mm: float, preset: NoisePreset
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The preset's chips on the artifact: centres (n, 2) mm, radii mm, peaks DN, glint peaks DN."""
    count = round(preset.flecks_per_mm * 2 * FEATURE_HALF_EXTENT_MM)
    cat = _catalogue(texture_seed).flecks[:, :count, :]
    # chips come in clusters where the paint was damaged: FLECKS_PER_CLUSTER consecutive entries share
    # their first entry's draw as the cluster's centre and spread over fleck_cluster_mm about it
    centre = cat[:, ::FLECKS_PER_CLUSTER, 0].repeat(FLECKS_PER_CLUSTER, axis=1)[:, :count]
    along = (2.0 * centre - 1.0) * FEATURE_HALF_EXTENT_MM + (cat[..., 0] - 0.5) * preset.fleck_cluster_mm
    across = (cat[..., 1] - 0.5) * groove_width_mm  # anywhere across the groove, on its walls too
    uv = np.concatenate([np.column_stack([along[0], across[0]]), np.column_stack([across[1], along[1]])])
    size, peak, glint = (np.concatenate(cat[..., k]) for k in (2, 3, 4))
    sigma = preset.fleck_sigma_min_mm + size * (preset.fleck_sigma_max_mm - preset.fleck_sigma_min_mm)
    peak_dn = preset.fleck_peak_min_dn + peak * (preset.fleck_peak_max_dn - preset.fleck_peak_min_dn)
    glint_dn = preset.fleck_glint_peak_dn * (0.5 + 0.5 * glint)
    return uv, sigma, peak_dn, glint_dn


def fleck_points(
    h: FloatArray, *, texture_seed: int, groove_width_mm: float, preset: NoisePreset
) -> FloatArray:
    """Where the preset's chips in the paint image, px (n, 2) (for tests: which frames show them)."""
    uv, *_ = _flecks(texture_seed, groove_width_mm, preset)
    return project_points(h, uv) if len(uv) else np.zeros((0, 2))


def fleck_image(
    h: FloatArray, shape: tuple[int, int], *, texture_seed: int, groove_width_mm: float, preset: NoisePreset
) -> Float32Array:
    """Chips in the paint, each with a glint: blurred Gaussian blobs, DN above the paint level.

    Parameters
    ----------
    h : numpy.ndarray, shape (3, 3)
        Artifact mm -> image px homography.
    shape : (int, int)
        Image shape.
    texture_seed : int
        The artifact's seed.
    groove_width_mm : float
        True groove width (a chip's centre lies anywhere across the groove).
    preset : NoisePreset
        Density, sizes, peaks and blur.

    Returns
    -------
    numpy.ndarray, shape ``shape``, float32
        Brightness above the paint, DN (to be weighted by the paint coverage: a chip is in the paint).
    """
    out = np.zeros(shape, dtype=np.float32)
    uv, sigma, peak_dn, glint_dn = _flecks(texture_seed, groove_width_mm, preset)
    if len(uv) == 0:
        return out
    for radius, peak in ((sigma, peak_dn), (sigma * GLINT_TO_FLECK_RADIUS, glint_dn)):
        xy, sigma_e, amp = _blurred(h, uv, radius, peak, preset.blur_sigma_px)
        near = _near_frame(xy, 4.5 * sigma_e, shape)
        add_blobs(out, xy[near], sigma_e[near], amp[near])
    return out


def _specks(texture_seed: int, preset: NoisePreset) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The preset's dust specks on the artifact: centres (n, 2) mm, radii mm, peaks DN."""
    count = round(preset.specks_per_mm2 * (2 * FEATURE_HALF_EXTENT_MM) ** 2)
    cat = _catalogue(texture_seed).specks[:count]
    sigma = preset.speck_sigma_min_mm + cat[:, 2] * (preset.speck_sigma_max_mm - preset.speck_sigma_min_mm)
    peak_dn = preset.speck_peak_min_dn + cat[:, 3] * (preset.speck_peak_max_dn - preset.speck_peak_min_dn)
    return np.asarray(cat[:, :2]), sigma, peak_dn


def speck_points(h: FloatArray, *, texture_seed: int, preset: NoisePreset) -> FloatArray:
    """Where the preset's dust specks image, px (n, 2) (for tests: which frames show them)."""
    uv, _, _ = _specks(texture_seed, preset)
    return project_points(h, uv) if len(uv) else np.zeros((0, 2))


def speck_image(
    h: FloatArray, shape: tuple[int, int], *, texture_seed: int, preset: NoisePreset
) -> Float32Array:
    """Bright dust specks on the artifact: blurred Gaussian blobs, DN.

    Parameters
    ----------
    h : numpy.ndarray, shape (3, 3)
        Artifact mm -> image px homography.
    shape : (int, int)
        Image shape.
    texture_seed : int
        The artifact's seed.
    preset : NoisePreset
        Density, sizes, peaks and blur.

    Returns
    -------
    numpy.ndarray, shape ``shape``, float32
        Brightness added to whatever lies under the speck (land or paint), DN.
    """
    out = np.zeros(shape, dtype=np.float32)
    uv, sigma, peak_dn = _specks(texture_seed, preset)
    if len(uv) == 0:
        return out
    xy, sigma_e, amp = _blurred(h, uv, sigma, peak_dn, preset.blur_sigma_px)
    near = _near_frame(xy, 4.5 * sigma_e, shape)
    add_blobs(out, xy[near], sigma_e[near], amp[near])
    return out


def _near_frame(xy: FloatArray, reach: FloatArray, shape: tuple[int, int]) -> np.ndarray:
    """Which blobs reach into the frame (a cheap test before the per-blob loop)."""
    return np.asarray(
        (xy[:, 0] + reach >= 0)
        & (xy[:, 0] - reach <= shape[1] - 1)
        & (xy[:, 1] + reach >= 0)
        & (xy[:, 1] - reach <= shape[0] - 1)
    )
