"""The simulated ruler camera: images of the graduated ruler with exact ground truth (issue 22).

Conventions
-----------
* Image and camera as in ``sim.artifact`` (pixel centres at integers, x right, y down; a pinhole
  with the ``CameraSpec``'s scale and working distance, principal point at the image centre).
* Ruler frame (mm): ``s`` along the ruler (graduation ``k`` centred at ``s = k * pitch``), ``t``
  across it, +90 deg from ``s`` (the design in ``station/vision/RULER.md``, ``RulerSpec``).
* View: the ruler point ``(anchor_mm, 0)`` plays the artifact origin of ``sim.artifact``'s ``Pose``:
  the ruler point ``(s, t)`` sits at ``T + R (s - anchor_mm, t, 0)`` in camera coordinates, so
  ``rotation_deg`` turns the ruler's +s direction to the image direction ``(cos, sin)``.
* Truth: ``position_mm`` and ``offset_mm`` are the ruler coordinates ``(s, t)`` of the point on the
  ruler's plane under the image's origin pixel (0, 0) (where that pixel's ray meets the plane);
  ``principal_position_mm`` and ``principal_offset_mm`` the same under the principal point.
  ``angle_deg`` is the image direction of the ruler's axis (the line ``t = 0``, a straight line in
  the image) toward increasing ``s``; positive turns image +x toward +y.

The pattern is rendered exactly where it matters: inside the graduation band (and the code track)
each pixel is the pixel-area average of the Gaussian-blurred pattern, summed edge by edge with
``box_step`` along each edge's own image line (straight under the homography). Only at the corners
of each line and cell is the coverage the product of the along and across coverages (exact for
pixel-aligned edges); no measurement claims truth there.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from sim._render_camera import CameraSpec, Pose, homography_for, spec_from_dict
from sim._render_features import vignetting_map
from sim._render_geometry import FloatArray, box_step, cutoff_px
from sim._ruler_surface import RulerSurface, get_surface, illumination_map, scratch_factor, speck_factor
from sim.presets import NoisePreset, get_preset
from station.vision import RulerSpec

__all__ = ["RulerTruth", "render_ruler", "ruler_coverage", "ruler_homography", "ruler_truth"]


def ruler_homography(pose: Pose, anchor_mm: float, camera: CameraSpec = CameraSpec()) -> FloatArray:  # noqa: B008
    """Homography ruler mm ``(s, t)`` -> image px, 3x3, ``H[2, 2]`` scaled to the anchor's depth."""
    shift = np.array([[1.0, 0.0, -anchor_mm], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(homography_for(pose, camera) @ shift)


def _to_ruler(h: FloatArray, x: float, y: float) -> tuple[float, float]:
    p = np.linalg.solve(h, np.array([x, y, 1.0]))
    return float(p[0] / p[2]), float(p[1] / p[2])


@dataclass(frozen=True, eq=False)
class RulerTruth:
    """Ground truth of one ruler image (conventions in the module docstring).

    Attributes
    ----------
    position_mm, offset_mm : float
        Ruler ``(s, t)`` under the origin pixel, mm.
    angle_deg : float
        Image direction of the ruler's axis toward +s, deg.
    principal_position_mm, principal_offset_mm : float
        Ruler ``(s, t)`` under the principal point, mm.
    homography : numpy.ndarray, shape (3, 3)
        Ruler mm -> image px.
    px_per_mm : float
        Image scale at the anchor's depth, px/mm.
    pose : Pose
        The pose rendered (of the ruler frame shifted to the anchor).
    anchor_mm : float
        The ruler position at the pose's origin, mm.
    """

    position_mm: float
    offset_mm: float
    angle_deg: float
    principal_position_mm: float
    principal_offset_mm: float
    homography: FloatArray
    px_per_mm: float
    pose: Pose
    anchor_mm: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "position_mm": self.position_mm,
            "offset_mm": self.offset_mm,
            "angle_deg": self.angle_deg,
            "principal_position_mm": self.principal_position_mm,
            "principal_offset_mm": self.principal_offset_mm,
            "homography": self.homography.tolist(),
            "px_per_mm": self.px_per_mm,
            "pose": self.pose.to_dict(),
            "anchor_mm": self.anchor_mm,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RulerTruth:
        """Inverse of ``to_dict`` (extra keys, such as a set entry's ``file``, are ignored)."""
        try:
            h = np.array(data["homography"], dtype=np.float64).reshape(3, 3)
            h.setflags(write=False)
            return cls(
                position_mm=float(data["position_mm"]),
                offset_mm=float(data["offset_mm"]),
                angle_deg=float(data["angle_deg"]),
                principal_position_mm=float(data["principal_position_mm"]),
                principal_offset_mm=float(data["principal_offset_mm"]),
                homography=h,
                px_per_mm=float(data["px_per_mm"]),
                pose=spec_from_dict(Pose, data["pose"]),
                anchor_mm=float(data["anchor_mm"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"ruler truth: malformed entry ({exc!r})") from exc

    def to_json(self) -> str:
        """``to_dict`` as a JSON string."""
        return json.dumps(self.to_dict())


def ruler_truth(
    pose: Pose,
    *,
    anchor_mm: float,
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
) -> RulerTruth:
    """Exact ground truth of the ruler seen at ``pose`` (its frame shifted to ``anchor_mm``)."""
    h = ruler_homography(pose, anchor_mm, camera)
    position, offset = _to_ruler(h, 0.0, 0.0)
    ppx, ppy = camera.principal_point
    principal_position, principal_offset = _to_ruler(h, ppx, ppy)
    a = h @ np.array([anchor_mm, 0.0, 1.0])
    b = h @ np.array([anchor_mm + 1.0, 0.0, 1.0])
    d = b[:2] / b[2] - a[:2] / a[2]
    h_ro = h.copy()
    h_ro.setflags(write=False)
    return RulerTruth(
        position_mm=position,
        offset_mm=offset,
        angle_deg=math.degrees(math.atan2(d[1], d[0])),
        principal_position_mm=principal_position,
        principal_offset_mm=principal_offset,
        homography=h_ro,
        px_per_mm=camera.focal_px / (camera.working_distance_mm + pose.z_mm),
        pose=pose,
        anchor_mm=anchor_mm,
    )


def _pixel_coords(h: FloatArray, shape: tuple[int, int]) -> tuple[FloatArray, FloatArray]:
    """Ruler ``(s, t)`` (mm) of every pixel centre."""
    g = np.linalg.inv(h)
    g = g / g[2, 2] if g[2, 2] != 0 else g
    ys = np.arange(shape[0], dtype=np.float64)[:, None]
    xs = np.arange(shape[1], dtype=np.float64)[None, :]
    den = g[2, 0] * xs + g[2, 1] * ys + g[2, 2]
    if np.any(den <= 0):
        raise ValueError("the ruler's plane does not face the camera over the whole frame")
    s = (g[0, 0] * xs + g[0, 1] * ys + g[0, 2]) / den
    t = (g[1, 0] * xs + g[1, 1] * ys + g[1, 2]) / den
    return np.asarray(s), np.asarray(t)


def _lines(h: FloatArray, axis: int, values: FloatArray) -> FloatArray:
    """Image lines ``a x + b y = c`` (unit normal toward increasing ruler coordinate) of the ruler
    lines ``coord[axis] = value``, (n, 3)."""
    g_t = np.linalg.inv(h).T
    ruler_lines = np.zeros((len(values), 3))
    ruler_lines[:, axis] = 1.0
    ruler_lines[:, 2] = -values
    img = ruler_lines @ g_t.T
    # l . (x, y, 1) = (coord - value) * w, with w the homogeneous scale of H^-1 (x, y, 1): make it > 0
    centre = np.linalg.inv(h) @ np.array([0.0, 0.0, 1.0])
    sign = 1.0 if centre[2] > 0 else -1.0
    norm = np.hypot(img[:, 0], img[:, 1])
    return np.column_stack([img[:, 0], img[:, 1], -img[:, 2]]) * (sign / norm)[:, None]


def _stripes(
    coord: FloatArray,
    xs: FloatArray,
    ys: FloatArray,
    bounds: FloatArray,
    lines_lo: FloatArray,
    lines_hi: FloatArray,
    sigma_px: float,
) -> FloatArray:
    """Blurred pixel coverage of the union of disjoint sorted intervals ``bounds`` (n, 2) of ``coord``.

    Each interval covers ``S(d_lo) - S(d_hi)`` of a pixel, ``d`` the pixel centre's signed distance
    to the image line of the interval's lower or upper bound (``lines_lo``, ``lines_hi``) and ``S``
    the blurred step ``box_step`` (the sharp step beyond its reach); ``coord``, the ruler coordinate
    of each pixel, only says which intervals are near: the others add exactly 0.
    """
    out = np.zeros(coord.shape)
    if len(bounds) == 0:
        return out
    idx = np.clip(np.searchsorted(bounds[:, 0], coord, side="right") - 1, 0, len(bounds) - 1)
    reach = cutoff_px(sigma_px)
    for shift in (-1, 0, 1):
        k = idx + shift
        valid = (k >= 0) & (k < len(bounds))
        kk = np.where(valid, k, 0)
        for lines, sign in ((lines_lo, 1.0), (lines_hi, -1.0)):
            d = lines[kk, 0] * xs + lines[kk, 1] * ys - lines[kk, 2]
            step = (d > 0).astype(np.float64)
            near = valid & (np.abs(d) < reach)
            if near.any():
                normal = lines[kk[near]]
                step[near] = box_step(d[near], np.abs(normal[:, 0]), np.abs(normal[:, 1]), sigma_px)
            out += np.where(valid, sign * step, 0.0)
    return np.clip(out, 0.0, 1.0)


def _runs(bits: npt.NDArray[np.uint8], first: int) -> list[tuple[int, int]]:
    """Runs of ones in ``bits`` as (first cell, last cell), cells numbered from ``first``."""
    padded = np.concatenate([[0], bits.astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(padded))
    return [(first + int(a), first + int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def ruler_coverage(
    pose: Pose,
    *,
    anchor_mm: float,
    blur_sigma_px: float,
    ruler: RulerSpec = RulerSpec(),  # noqa: B008 - frozen model, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
) -> FloatArray:
    """The pattern's blurred pixel coverage: 1 on the dark marks (lines and code cells), 0 on the ground.

    Returns
    -------
    numpy.ndarray, shape (height, width), float64
        In the graduation band away from the line ends, exactly the pixel average of the blurred marks.
    """
    if not (blur_sigma_px >= 0 and math.isfinite(blur_sigma_px)):
        raise ValueError(f"blur_sigma_px must be a finite value >= 0, got {blur_sigma_px!r}")
    h = ruler_homography(pose, anchor_mm, camera)
    s, t = _pixel_coords(h, camera.shape)
    out = np.zeros(camera.shape)
    scale = camera.focal_px / (camera.working_distance_mm + pose.z_mm)
    margin = 2.0 * cutoff_px(blur_sigma_px) / scale + 0.05
    t0, t1 = ruler.band_mm
    region = (
        (t > t0 - margin)
        & (t < t1 + margin)
        & (s > -margin - ruler.pitch_mm)
        & (s < ruler.length_mm + ruler.pitch_mm + margin)
    )
    if not region.any():
        return out
    rows, cols = np.nonzero(region)
    xs, ys = cols.astype(np.float64), rows.astype(np.float64)
    sr, tr = s[region], t[region]
    lo_k = max(math.floor(sr.min() / ruler.pitch_mm) - 1, 0)
    hi_k = min(math.ceil(sr.max() / ruler.pitch_mm) + 1, ruler.graduation_count - 1)
    half = ruler.line_width_mm / 2
    marks = np.zeros(len(sr))
    if lo_k <= hi_k:
        centres = np.arange(lo_k, hi_k + 1) * ruler.pitch_mm
        bounds = np.column_stack([centres - half, centres + half])
        along = _stripes(
            sr, xs, ys, bounds, _lines(h, 0, bounds[:, 0]), _lines(h, 0, bounds[:, 1]), blur_sigma_px
        )
        band = np.array(ruler.line_segments_mm)
        across = _stripes(tr, xs, ys, band, _lines(h, 1, band[:, 0]), _lines(h, 1, band[:, 1]), blur_sigma_px)
        marks += along * across
    cell = ruler.cell_mm
    lo_j = max(math.floor(sr.min() / cell) - 1, 0)
    hi_j = min(math.ceil(sr.max() / cell) + 1, ruler.cell_count - 1)
    if lo_j <= hi_j:
        runs = _runs(ruler.code_bits()[lo_j : hi_j + 1], lo_j)
        if runs:
            bounds = np.array([[(a - 0.5) * cell, (b + 0.5) * cell] for a, b in runs])
            along = _stripes(
                sr, xs, ys, bounds, _lines(h, 0, bounds[:, 0]), _lines(h, 0, bounds[:, 1]), blur_sigma_px
            )
            track = np.array([ruler.code_track_mm])
            across = _stripes(
                tr, xs, ys, track, _lines(h, 1, track[:, 0]), _lines(h, 1, track[:, 1]), blur_sigma_px
            )
            marks += along * across
    out[region] = np.clip(marks, 0.0, 1.0)
    return out


def render_ruler(
    pose: Pose,
    *,
    anchor_mm: float,
    preset: NoisePreset | str = "nominal",
    surface: RulerSurface | None = None,
    ruler: RulerSpec = RulerSpec(),  # noqa: B008 - frozen model, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
    texture_seed: int = 0,
    rng: np.random.Generator,
) -> tuple[npt.NDArray[np.uint8], RulerTruth]:
    """Render one 8-bit camera frame of the ruler, with its ground truth.

    Parameters
    ----------
    pose : Pose
        Pose of the ruler frame shifted to ``anchor_mm`` (module docstring).
    anchor_mm : float
        Ruler position at the pose's origin, mm.
    preset : NoisePreset or str
        Noise preset (blur, grey levels: ground = land level, marks = paint level; noise; vignetting).
    surface : RulerSurface, optional
        Light and defects; default the one named as the preset.
    ruler : RulerSpec
        The ruler.
    camera : CameraSpec
        The camera.
    texture_seed : int
        Seed of the ruler's specks and scratches (fixed to the ruler).
    rng : numpy.random.Generator
        Source of the frame's noise.

    Returns
    -------
    image : numpy.ndarray, shape (height, width), uint8
    truth : RulerTruth

    Notes
    -----
    Grey level before noise: ``(ground + marks (mark - ground)) * specks``, pulled toward mid-grey
    by scratches, plus bright specks, times vignetting and the illumination gradient. Noise as the
    cross's: Gaussian with variance ``read^2 + gain * signal``, rounding, clipping, salt and pepper.
    """
    p = get_preset(preset) if isinstance(preset, str) else preset
    surf = get_surface(p.name) if surface is None else surface
    truth = ruler_truth(pose, anchor_mm=anchor_mm, camera=camera)
    shape = camera.shape
    h = truth.homography
    marks = ruler_coverage(
        pose, anchor_mm=anchor_mm, blur_sigma_px=p.blur_sigma_px, ruler=ruler, camera=camera
    )
    clean = (p.land_level_dn + marks * (p.paint_level_dn - p.land_level_dn)).astype(np.float32)
    features = {
        "surface": surf,
        "texture_seed": texture_seed,
        "length_mm": ruler.length_mm,
        "band_mm": ruler.band_mm,
        "blur_sigma_px": p.blur_sigma_px,
    }
    factor, bright = speck_factor(h, shape, **features)  # type: ignore[arg-type]
    clean *= factor
    scratch = scratch_factor(h, shape, **features)  # type: ignore[arg-type]
    mid = np.float32(0.5 * (p.land_level_dn + p.paint_level_dn))
    clean += scratch * (mid - clean) + bright
    clean *= vignetting_map(shape, p.vignetting) * illumination_map(shape, surf.gradient, surf.gradient_deg)
    variance = np.float32(p.read_noise_dn**2) + np.float32(p.shot_noise_gain_dn_per_e) * np.maximum(clean, 0)
    noisy = clean + np.sqrt(variance) * rng.standard_normal(shape, dtype=np.float32)
    image = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    if p.salt_pepper_fraction > 0:
        flat = image.reshape(-1)
        count = int(rng.binomial(flat.size, p.salt_pepper_fraction))
        flat[rng.integers(0, flat.size, count)] = rng.integers(0, 2, count, dtype=np.uint8) * np.uint8(255)
    return image, truth
