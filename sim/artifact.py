"""The simulated artifact camera: crossed-groove images with exact ground truth.

Conventions
-----------
* Image: pixel centres at integer ``(x, y)``, 0-based, x right, y down (OpenCV); pixel ``(r, c)``
  covers ``[c - 0.5, c + 0.5] x [r - 0.5, r + 0.5]``.
* Artifact frame (mm): origin at the crossing of the two groove centrelines, ``u`` along the
  "horizontal" groove, ``v`` along the "vertical" one, same handedness as the image. The horizontal
  groove is ``|v| <= w/2``, the vertical groove ``|u| <= w/2`` (``w`` the true width); the four
  lands are the quadrants outside both, each with its corner at the crossing rounded.
* Camera frame (mm): X right, Y down, Z forward along the optical axis. A pinhole with focal length
  ``px_per_mm * working_distance_mm`` (px) images the focal plane (Z = working distance) at
  ``px_per_mm``; the principal point is the image centre ``((W - 1)/2, (H - 1)/2)``.
* Pose: the artifact point ``(u, v)`` sits at ``t + R (u, v, 0)`` with
  ``t = (x_mm, y_mm, working_distance + z_mm)`` and ``R = Rx(tilt_x) Ry(tilt_y) Rz(rotation)``
  (right-handed rotations about the camera axes). So ``rotation_deg`` turns the u axis to the image
  direction ``(cos, sin)``: positive is clockwise on screen (y down). Positive ``tilt_x`` moves the
  +y side of the artifact away from the camera; positive ``tilt_y`` moves the +x side toward it.
  The homography artifact mm -> image px is ``K [r1 r2 t]``, used both to render and for truth.
* Truth: corners are the images of ``(-w/2, -w/2), (+w/2, -w/2), (+w/2, +w/2), (-w/2, +w/2)`` (they
  map to the square ``(0,0), (w,0), (w,w), (0,w)``); the centre is the image of ``(0, 0)``, the
  crossing of the projected square's diagonals; lines ``a x + b y = c`` (``a^2 + b^2 = 1``) are the
  top (v = -w/2), bottom (v = +w/2), left (u = -w/2) and right (u = +w/2) edges, with the normal
  ``(a, b)`` pointing toward increasing v (top, bottom) or increasing u (left, right).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from sim._render_camera import (
    INCH_MM,
    ArtifactSpec,
    CameraSpec,
    Pose,
    homography_for,
    pose_for_center_px,
    spec_from_dict,
)
from sim._render_features import (
    glint_image,
    local_scale,
    scratch_image,
    streak_texture,
    vignetting_map,
)
from sim._render_geometry import FloatArray, land_fraction
from sim._render_specks import fleck_image, speck_image
from sim.presets import NoisePreset, get_preset

__all__ = [
    "INCH_MM",
    "ArtifactSpec",
    "CameraSpec",
    "Pose",
    "Truth",
    "homography_for",
    "pose_for_center_px",
    "render",
    "render_ideal",
    "spec_from_dict",
    "truth_for",
]


def _arr(data: Any, shape: tuple[int, ...]) -> FloatArray:
    out = np.array(data, dtype=np.float64).reshape(shape)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class Truth:
    """Ground truth of one image (conventions in the module docstring).

    Attributes
    ----------
    center_px : (float, float)
        Image of the artifact origin, px.
    corners_px : numpy.ndarray, shape (4, 2)
        Images of the groove-square corners, px, order (-,-), (+,-), (+,+), (-,+) in (u, v).
    lines : numpy.ndarray, shape (4, 3)
        Edges ``a x + b y = c`` (unit normal), order top, bottom, left, right.
    homography : numpy.ndarray, shape (3, 3)
        Artifact mm -> image px.
    groove_width_mm : float
        True groove width, mm.
    px_per_mm : float
        Image scale at the artifact origin's depth, px/mm (the camera's when ``z_mm = 0``).
    pose : Pose
        The pose rendered.
    """

    center_px: tuple[float, float]
    corners_px: FloatArray
    lines: FloatArray
    homography: FloatArray
    groove_width_mm: float
    px_per_mm: float
    pose: Pose

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (lists of floats)."""
        return {
            "center_px": [float(v) for v in self.center_px],
            "corners_px": self.corners_px.tolist(),
            "lines": self.lines.tolist(),
            "homography": self.homography.tolist(),
            "groove_width_mm": float(self.groove_width_mm),
            "px_per_mm": float(self.px_per_mm),
            "pose": self.pose.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Truth:
        """Inverse of ``to_dict`` (extra keys, such as an image-set entry's ``file``, are ignored)."""
        try:
            cx, cy = (float(v) for v in data["center_px"])
            return cls(
                center_px=(cx, cy),
                corners_px=_arr(data["corners_px"], (4, 2)),
                lines=_arr(data["lines"], (4, 3)),
                homography=_arr(data["homography"], (3, 3)),
                groove_width_mm=float(data["groove_width_mm"]),
                px_per_mm=float(data["px_per_mm"]),
                pose=spec_from_dict(Pose, data["pose"]),
            )
        except (KeyError, TypeError) as exc:
            raise ValueError(f"truth: malformed entry ({exc!r})") from exc

    def to_json(self) -> str:
        """``to_dict`` as a JSON string."""
        return json.dumps(self.to_dict())

    @classmethod
    def from_json(cls, text: str | Mapping[str, Any]) -> Truth:
        """Inverse of ``to_json``; also accepts the already-parsed dict."""
        return cls.from_dict(json.loads(text) if isinstance(text, str) else text)


def _edge_line(h_inv_t: FloatArray, coeffs: tuple[float, float, float]) -> FloatArray:
    line = h_inv_t @ np.array(coeffs)
    return np.asarray(np.array([line[0], line[1], -line[2]]) / math.hypot(line[0], line[1]))


def truth_for(
    pose: Pose,
    *,
    artifact: ArtifactSpec = ArtifactSpec(),  # noqa: B008 - frozen dataclass, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
) -> Truth:
    """Exact ground truth of the image of ``artifact`` at ``pose``.

    Parameters
    ----------
    pose : Pose
        Pose of the artifact relative to the camera.
    artifact : ArtifactSpec
        The artifact (its true groove width sets the corners and lines).
    camera : CameraSpec
        The camera.

    Returns
    -------
    Truth
        Centre, corners (4, 2), lines (4, 3) in px, homography, true width and scale.
    """
    h = homography_for(pose, camera)
    half = artifact.groove_width_mm / 2.0
    square = np.array([[-half, -half, 1.0], [half, -half, 1.0], [half, half, 1.0], [-half, half, 1.0]])
    proj = square @ h.T
    corners = proj[:, :2] / proj[:, 2:3]
    h_inv_t = np.asarray(np.linalg.inv(h), dtype=np.float64).T
    # An artifact line l (l . (u, v, 1) = 0) images to H^-T l; H[2, 2] > 0 keeps the side signs.
    lines = np.stack(
        [
            _edge_line(h_inv_t, (0.0, 1.0, half)),  # top: v = -w/2
            _edge_line(h_inv_t, (0.0, 1.0, -half)),  # bottom: v = +w/2
            _edge_line(h_inv_t, (1.0, 0.0, half)),  # left: u = -w/2
            _edge_line(h_inv_t, (1.0, 0.0, -half)),  # right: u = +w/2
        ]
    )
    depth = camera.working_distance_mm + pose.z_mm
    return Truth(
        center_px=(float(h[0, 2]), float(h[1, 2])),
        corners_px=_arr(corners, (4, 2)),
        lines=_arr(lines, (4, 3)),
        homography=_arr(h, (3, 3)),
        groove_width_mm=artifact.groove_width_mm,
        px_per_mm=camera.focal_px / depth,
        pose=pose,
    )


def _land(truth: Truth, artifact: ArtifactSpec, camera: CameraSpec, sigma_px: float) -> FloatArray:
    radius_px = artifact.corner_radius_mm * local_scale(
        truth.homography, np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * artifact.groove_width_mm / 2
    )
    return land_fraction(truth.lines, camera.shape, sigma_px=sigma_px, corner_radius_px=list(radius_px))


def render_ideal(
    pose: Pose,
    *,
    blur_sigma_px: float,
    artifact: ArtifactSpec = ArtifactSpec(),  # noqa: B008 - frozen dataclass, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
) -> FloatArray:
    """The exact area-integrated, blurred geometry: land coverage without texture or noise.

    Parameters
    ----------
    pose : Pose
        Pose of the artifact.
    blur_sigma_px : float
        Gaussian optical blur, px (0: pure pixel-area coverage).
    artifact, camera : ArtifactSpec, CameraSpec
        The artifact and camera.

    Returns
    -------
    numpy.ndarray, shape (height, width), float64
        1 on the lands, 0 in the grooves; along straight edges farther than the corner radius plus
        ``7.5 sigma + 1`` px from the crossing, exactly the pixel average of the blurred step.
    """
    if not (blur_sigma_px >= 0 and math.isfinite(blur_sigma_px)):
        raise ValueError(f"blur_sigma_px must be a finite value >= 0, got {blur_sigma_px!r}")
    return _land(truth_for(pose, artifact=artifact, camera=camera), artifact, camera, blur_sigma_px)


def render(
    pose: Pose,
    *,
    preset: NoisePreset | str = "nominal",
    artifact: ArtifactSpec = ArtifactSpec(),  # noqa: B008 - frozen dataclass, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
    rng: np.random.Generator,
) -> tuple[npt.NDArray[np.uint8], Truth]:
    """Render one 8-bit camera frame of the artifact, with its ground truth.

    Parameters
    ----------
    pose : Pose
        Pose of the artifact.
    preset : NoisePreset or str
        Noise preset or its name (``"nominal"``, ``"hard"``, ``"hard-specks"``).
    artifact, camera : ArtifactSpec, CameraSpec
        The artifact (width, corner radius, texture seed) and camera.
    rng : numpy.random.Generator
        Source of the frame's noise (read, shot, salt-and-pepper); features do not depend on it.

    Returns
    -------
    image : numpy.ndarray, shape (height, width), uint8
        The frame.
    truth : Truth
        Its ground truth.

    Notes
    -----
    Grey level before noise: ``paint + glints + flecks + L (land + texture - scratches - paint - glints
    - flecks) + specks`` with ``L`` the exact land coverage (``render_ideal``), times the vignetting.
    Noise is Gaussian with variance ``read^2 + gain * signal``; then rounding, clipping to 0-255, salt
    and pepper.
    """
    p = get_preset(preset) if isinstance(preset, str) else preset
    truth = truth_for(pose, artifact=artifact, camera=camera)
    shape = camera.shape
    h = truth.homography
    land = _land(truth, artifact, camera, p.blur_sigma_px).astype(np.float32)
    land_dn = np.full(shape, p.land_level_dn, dtype=np.float32)
    if p.texture_rms_dn > 0:
        texture = streak_texture(
            np.asarray(np.linalg.inv(h), dtype=np.float64),
            shape,
            texture_seed=artifact.texture_seed,
            sigma_px=p.blur_sigma_px,
            px_per_mm=truth.px_per_mm,
        )
        land_dn += np.float32(p.texture_rms_dn) * texture
    land_dn -= scratch_image(h, shape, texture_seed=artifact.texture_seed, preset=p)
    paint_dn = np.float32(p.paint_level_dn) + glint_image(
        h, shape, texture_seed=artifact.texture_seed, groove_width_mm=artifact.groove_width_mm, preset=p
    )
    if p.flecks_per_mm > 0:
        paint_dn += fleck_image(
            h, shape, texture_seed=artifact.texture_seed, groove_width_mm=artifact.groove_width_mm, preset=p
        )
    scene = paint_dn + land * (land_dn - paint_dn)
    if p.specks_per_mm2 > 0:
        scene += speck_image(h, shape, texture_seed=artifact.texture_seed, preset=p)
    clean = scene * vignetting_map(shape, p.vignetting)
    variance = np.float32(p.read_noise_dn**2) + np.float32(p.shot_noise_gain_dn_per_e) * np.maximum(clean, 0)
    noisy = clean + np.sqrt(variance) * rng.standard_normal(shape, dtype=np.float32)
    image = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    if p.salt_pepper_fraction > 0:
        flat = image.reshape(-1)
        count = int(rng.binomial(flat.size, p.salt_pepper_fraction))
        flat[rng.integers(0, flat.size, count)] = rng.integers(0, 2, count, dtype=np.uint8) * np.uint8(255)
    return image, truth
