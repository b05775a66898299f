"""What the simulated ruler's frames show besides its pattern: light, dust specks and scratches.

A ``RulerSurface`` is the ruler's counterpart of the noise preset's surface values (the noise, blur,
grey levels and vignetting come from the ``NoisePreset`` of the same name, ``sim.presets``). Specks
and scratches are fixed to the ruler: drawn once from its ``texture_seed`` in ruler coordinates (mm)
over its whole length and mapped into each image through the view's homography, so that they move
with the ruler. The illumination gradient is fixed to the camera (a ring light off the optical axis).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.special import ndtr

from sim._render_features import local_scale, project_points
from sim._render_geometry import Float32Array, FloatArray, box_step, cutoff_px

__all__ = ["SURFACES", "RulerSurface", "get_surface", "illumination_map", "scratch_factor", "speck_factor"]

#: Ruler margin beyond each end and beyond the pattern's band over which features are drawn, mm.
FEATURE_MARGIN_MM = 5.0


@dataclass(frozen=True)
class RulerSurface:
    """Light and defects of the simulated ruler's frames (lengths on the ruler in mm).

    Attributes
    ----------
    name : str
        Name, as the noise preset it goes with (``nominal``, ``hard``).
    version : int
        Bumped whenever a value changes (benchmarks quote it).
    gradient : float
        Fractional brightness change from the frame's centre to its edge along ``gradient_deg``.
    gradient_deg : float
        Image direction of increasing brightness, deg (x right, y down).
    specks_per_mm2 : float
        Dust specks per mm^2 of ruler surface.
    speck_sigma_min_mm, speck_sigma_max_mm : float
        Range of a speck's Gaussian radius, mm.
    speck_depth_min, speck_depth_max : float
        Range of a dark speck's darkening at its core (fraction of the local grey level).
    bright_speck_fraction : float
        Fraction of specks that are bright (light scattered by dust), ``speck_depth`` x 255 DN above.
    scratch_spacing_mm : float
        Mean distance along the ruler between scratches across the graduations; 0 for none.
    scratch_width_mm : float
        Largest scratch width, mm.
    scratch_strength : float
        How far a scratch pulls the grey level toward mid-grey at its core (0 none, 1 fully).
    """

    name: str
    version: int
    gradient: float
    gradient_deg: float
    specks_per_mm2: float
    speck_sigma_min_mm: float
    speck_sigma_max_mm: float
    speck_depth_min: float
    speck_depth_max: float
    bright_speck_fraction: float
    scratch_spacing_mm: float
    scratch_width_mm: float
    scratch_strength: float

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            number = isinstance(value, float | int) and not isinstance(value, bool)
            if number and f.name != "gradient_deg" and not (math.isfinite(value) and value >= 0):
                raise ValueError(f"ruler surface {self.name!r}: {f.name} must be finite and >= 0")
        if self.gradient >= 1 or self.speck_depth_max > 1 or self.scratch_strength > 1:
            raise ValueError(
                f"ruler surface {self.name!r}: gradient, speck depth and scratch strength below 1"
            )

    def to_dict(self) -> dict[str, Any]:
        """All values as a JSON-ready dict."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RulerSurface:
        """Inverse of ``to_dict``; ValueError naming missing or unknown keys."""
        names = {f.name for f in fields(cls)}
        missing, unknown = names - set(data), set(data) - names
        if missing or unknown:
            raise ValueError(f"ruler surface: missing keys {sorted(missing)}, unknown keys {sorted(unknown)}")
        return cls(**dict(data))


NOMINAL = RulerSurface(
    name="nominal",
    version=1,
    gradient=0.05,
    gradient_deg=30.0,
    specks_per_mm2=0.2,
    speck_sigma_min_mm=0.002,
    speck_sigma_max_mm=0.006,
    speck_depth_min=0.05,
    speck_depth_max=0.3,
    bright_speck_fraction=0.0,
    scratch_spacing_mm=0.0,
    scratch_width_mm=0.0,
    scratch_strength=0.0,
)

HARD = RulerSurface(
    name="hard",
    version=1,
    gradient=0.3,
    gradient_deg=30.0,
    specks_per_mm2=2.0,
    speck_sigma_min_mm=0.003,
    speck_sigma_max_mm=0.015,
    speck_depth_min=0.2,
    speck_depth_max=0.8,
    bright_speck_fraction=0.3,
    scratch_spacing_mm=4.0,
    scratch_width_mm=0.02,
    scratch_strength=0.8,
)

SURFACES: dict[str, RulerSurface] = {s.name: s for s in (NOMINAL, HARD)}
"""The ruler surfaces by name, one per noise preset."""


def get_surface(name: str) -> RulerSurface:
    """The surface called ``name``; ValueError naming the choices when there is none."""
    try:
        return SURFACES[name]
    except KeyError:
        raise ValueError(f"unknown ruler surface {name!r}; choose one of: {', '.join(SURFACES)}") from None


@lru_cache(maxsize=8)
def illumination_map(shape: tuple[int, int], gradient: float, direction_deg: float) -> Float32Array:
    """Linear brightness factor ``1 + gradient * r`` with ``r`` from -1 to 1 along the direction."""
    height, width = shape
    c, s = math.cos(math.radians(direction_deg)), math.sin(math.radians(direction_deg))
    ys = (np.arange(height) - (height - 1) / 2.0)[:, None]
    xs = (np.arange(width) - (width - 1) / 2.0)[None, :]
    reach = abs(c) * (width - 1) / 2.0 + abs(s) * (height - 1) / 2.0
    out = (1.0 + gradient * (xs * c + ys * s) / reach).astype(np.float32)
    out.setflags(write=False)
    return out


def _rng(texture_seed: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([int(texture_seed), 0x2B1E, stream])


@lru_cache(maxsize=8)
def _speck_catalogue(texture_seed: int, length_mm: float, band: tuple[float, float]) -> FloatArray:
    """Unit draws per speck: (s, t, size, depth, brightness), at 10 specks per mm^2 (the densest)."""
    area = (length_mm + 2 * FEATURE_MARGIN_MM) * (band[1] - band[0] + 2 * FEATURE_MARGIN_MM)
    draws = _rng(texture_seed, 1).random((round(10.0 * area), 5))
    draws[:, 0] = -FEATURE_MARGIN_MM + draws[:, 0] * (length_mm + 2 * FEATURE_MARGIN_MM)
    draws[:, 1] = band[0] - FEATURE_MARGIN_MM + draws[:, 1] * (band[1] - band[0] + 2 * FEATURE_MARGIN_MM)
    draws.setflags(write=False)
    return draws


def speck_factor(
    h: FloatArray,
    shape: tuple[int, int],
    *,
    surface: RulerSurface,
    texture_seed: int,
    length_mm: float,
    band_mm: tuple[float, float],
    blur_sigma_px: float,
) -> tuple[Float32Array, Float32Array]:
    """Dust specks: a multiplicative factor (dark specks) and an additive image (bright ones), DN.

    Each speck is a Gaussian spot on the ruler, blurred by the optics and the pixel box (its integral
    kept); ``h`` maps ruler mm to image px.
    """
    factor = np.ones(shape, dtype=np.float32)
    bright = np.zeros(shape, dtype=np.float32)
    area = (length_mm + 2 * FEATURE_MARGIN_MM) * (band_mm[1] - band_mm[0] + 2 * FEATURE_MARGIN_MM)
    count = round(surface.specks_per_mm2 * area)
    if count == 0:
        return factor, bright
    cat = _speck_catalogue(texture_seed, length_mm, band_mm)[:count]
    st = cat[:, :2]
    xy = project_points(h, st)
    inside = (xy[:, 0] > -50) & (xy[:, 0] < shape[1] + 50) & (xy[:, 1] > -50) & (xy[:, 1] < shape[0] + 50)
    for k in np.flatnonzero(inside):
        sigma_g = (
            surface.speck_sigma_min_mm + cat[k, 2] * (surface.speck_sigma_max_mm - surface.speck_sigma_min_mm)
        ) * float(local_scale(h, st[k : k + 1])[0])
        sigma_e = math.sqrt(sigma_g**2 + blur_sigma_px**2 + 1.0 / 12.0)
        depth = surface.speck_depth_min + cat[k, 3] * (surface.speck_depth_max - surface.speck_depth_min)
        amp = depth * (sigma_g / sigma_e) ** 2
        cx, cy = xy[k]
        half = 4.5 * sigma_e
        x0, x1 = max(int(cx - half), 0), min(int(cx + half) + 2, shape[1])
        y0, y1 = max(int(cy - half), 0), min(int(cy + half) + 2, shape[0])
        if x0 >= x1 or y0 >= y1:
            continue
        ys = np.arange(y0, y1, dtype=np.float64)[:, None] - cy
        xs = np.arange(x0, x1, dtype=np.float64)[None, :] - cx
        spot = np.exp(-(xs * xs + ys * ys) / (2.0 * sigma_e * sigma_e))
        if cat[k, 4] < surface.bright_speck_fraction:
            bright[y0:y1, x0:x1] += (255.0 * amp * spot).astype(np.float32)
        else:
            factor[y0:y1, x0:x1] *= (1.0 - amp * spot).astype(np.float32)
    return factor, bright


@lru_cache(maxsize=8)
def _scratch_catalogue(texture_seed: int, length_mm: float, spacing_mm: float) -> FloatArray:
    """Per scratch: (s, angle from the t axis in rad, length draw, width draw), one per ``spacing``."""
    count = max(1, round((length_mm + 2 * FEATURE_MARGIN_MM) / spacing_mm))
    rng = _rng(texture_seed, 2)
    s = -FEATURE_MARGIN_MM + (np.arange(count) + rng.uniform(0.1, 0.9, count)) * spacing_mm
    out = np.column_stack([s, rng.uniform(-1.0, 1.0, count), rng.random(count), rng.random(count)])
    out.setflags(write=False)
    return out


def scratch_factor(
    h: FloatArray,
    shape: tuple[int, int],
    *,
    surface: RulerSurface,
    texture_seed: int,
    length_mm: float,
    band_mm: tuple[float, float],
    blur_sigma_px: float,
) -> Float32Array:
    """Scratches across the graduations: the weight (0-``strength``) pulling each pixel to mid-grey.

    A scratch crosses the whole pattern band at up to 57 deg from the graduation lines, 40-100 % of
    ``scratch_width_mm`` wide, exactly area-integrated across and tapered at its ends.
    """
    out = np.zeros(shape, dtype=np.float32)
    if surface.scratch_spacing_mm <= 0 or surface.scratch_strength <= 0:
        return out
    cat = _scratch_catalogue(texture_seed, length_mm, surface.scratch_spacing_mm)
    span = band_mm[1] - band_mm[0]
    mid_t = 0.5 * (band_mm[0] + band_mm[1])
    ys_all = np.arange(shape[0], dtype=np.float64)[:, None]
    xs_all = np.arange(shape[1], dtype=np.float64)[None, :]
    for s0, angle, length_draw, width_draw in cat:
        half_len = 0.5 * span * (1.1 + 0.6 * length_draw) / max(math.cos(angle), 0.3)
        direction = np.array([math.sin(angle), math.cos(angle)])  # (s, t): mostly across the ruler
        centre = np.array([s0, mid_t])
        ends = project_points(h, np.stack([centre - half_len * direction, centre + half_len * direction]))
        lo, hi = ends.min(axis=0) - 20, ends.max(axis=0) + 20
        if hi[0] < 0 or hi[1] < 0 or lo[0] > shape[1] - 1 or lo[1] > shape[0] - 1:
            continue
        axis = ends[1] - ends[0]
        length_px = float(np.hypot(*axis))
        axis = axis / length_px
        normal = np.array([-axis[1], axis[0]])
        half_w = 0.5 * surface.scratch_width_mm * (0.4 + 0.6 * width_draw)
        half_w *= float(local_scale(h, centre[None, :])[0])
        x0, x1 = max(int(lo[0]), 0), min(int(hi[0]) + 1, shape[1])
        y0, y1 = max(int(lo[1]), 0), min(int(hi[1]) + 1, shape[0])
        rel_x, rel_y = xs_all[:, x0:x1] - ends[0][0], ys_all[y0:y1] - ends[0][1]
        across = rel_x * normal[0] + rel_y * normal[1]
        along = rel_x * axis[0] + rel_y * axis[1]
        near = np.abs(across) < half_w + cutoff_px(blur_sigma_px)
        ca, sa = abs(normal[0]), abs(normal[1])
        profile = np.zeros(across.shape)
        profile[near] = box_step(across[near] + half_w, ca, sa, blur_sigma_px) - box_step(
            across[near] - half_w, ca, sa, blur_sigma_px
        )
        taper = ndtr(along / 2.0) * ndtr((length_px - along) / 2.0)
        out[y0:y1, x0:x1] += (surface.scratch_strength * profile * taper).astype(np.float32)
    return np.minimum(out, np.float32(surface.scratch_strength))
