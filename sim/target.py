"""The simulated camera looking at the camera-calibration target, through its true lens, with exact truth.

The target (``station.camcal.CharucoTarget``) is a face of black and white cells on a grid: chessboard
squares and marker bits, ``cell_mm`` apart. The renderer is the crossed-groove artifact's
(``sim._render_geometry``): each pixel's value is the average over its square of the scene blurred by the
optics' Gaussian, and for a straight edge that is ``box_step`` of the pixel's signed distance to it. Here
every pixel centre is traced back through the true camera (``sim.lens``: OpenCV's pinhole and distortion,
inverted to 1e-6 px or better) onto the target's plane, where the cell lines around it are straight; the
coverage of each cell column and row is the difference of two ``box_step`` values, and the pixel the sum
over the cells near it of (column coverage) x (row coverage) x (the cell's reflectance). Exact along an
edge; at a corner the product of the two directions is exact for edges along the pixel grid and, like the
artifact's land corners, point-symmetric otherwise, so a chessboard corner's image is its true position.
The kernels (``sim._render_target``) skip the ``box_step`` of cell lines with no colour change across them
(they drop out of the sum exactly), work in bands of rows, and keep each true camera's pixel rays: the
same frames, to rounding, for about a third of the CPU.

Defocus: the blur grows with the distance from the focal plane, ``hypot(preset blur, defocus_px_per_mm
x |depth - focus_mm|)`` as ``sim.world`` has it, point by point for a tilted target: the light of each
point of the in-focus image is spread further by a Gaussian whose sigma follows its depth, interpolated
between a stack of blurs (an approximation). Grey levels, vignetting and the sensor's
read and shot noise come from the noise preset (``sim.presets``); the target is clean (no texture,
scratches or glints).

Truth (:class:`TargetTruth`): every corner's image by OpenCV's ``projectPoints`` with the true camera,
its depth and blur, and the pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from sim._render_camera import F4_DEFOCUS_PX_PER_MM
from sim._render_geometry import Float32Array, FloatArray
from sim._render_target import cached_vignetting, pixel_rays, scene, target_face
from sim.presets import NoisePreset, get_preset
from station.camcal import STANDARD_TARGET, CharucoTarget, ViewSpec
from station.camera_model import CameraIntrinsics

__all__ = [
    "F4_DEFOCUS_PX_PER_MM",
    "WORLD_DEFOCUS_PX_PER_MM",
    "TargetPose",
    "TargetTruth",
    "render_target",
    "sensor_readout",
]

WORLD_DEFOCUS_PX_PER_MM = F4_DEFOCUS_PX_PER_MM
"""``sim.world.WorldSpec.defocus_px_per_mm``'s default: f/4 since issue 22 (it was 20 px/mm, an f/0.6
lens, which does not exist)."""

_BLUR_LEVELS = np.array(
    [0.0, 0.35, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0, 5.6, 8.0, 11.0, 16.0, 22.0, 32.0, 45.0, 64.0]
)


@dataclass(frozen=True)
class TargetPose:
    """The target's frame in the camera's: ``X_cam = rotation @ X_target + translation_mm``."""

    rotation: FloatArray
    translation_mm: FloatArray

    def __post_init__(self) -> None:
        R = np.array(self.rotation, dtype=np.float64).reshape(3, 3)
        t = np.array(self.translation_mm, dtype=np.float64).reshape(3)
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
            raise ValueError("rotation must be a proper rotation matrix")
        if not np.all(np.isfinite(t)):
            raise ValueError("translation_mm must be finite")
        object.__setattr__(self, "rotation", R)
        object.__setattr__(self, "translation_mm", t)

    @classmethod
    def from_view(
        cls, view: ViewSpec, *, target: CharucoTarget = STANDARD_TARGET, working_distance_mm: float = 68.0
    ) -> TargetPose:
        """The target's pose in the camera after ``view``'s motion from the square pose (target centred)."""
        w, h = target.size_mm
        square = np.eye(4)
        square[:3, 3] = (-w / 2.0, -h / 2.0, working_distance_mm)
        T = np.linalg.solve(view.camera_motion(working_distance_mm), square)
        return cls(np.asarray(T[:3, :3], dtype=np.float64), np.asarray(T[:3, 3], dtype=np.float64))

    @property
    def rvec(self) -> FloatArray:
        """The rotation as OpenCV's Rodrigues vector."""
        return np.asarray(cv2.Rodrigues(self.rotation)[0].ravel(), dtype=np.float64)


@dataclass(frozen=True, eq=False)
class TargetTruth:
    """Ground truth of one target image.

    ``corners_px`` (N, 2): every corner's image (row = corner id), NaN behind the camera; ``in_frame``
    (N,): inside the image (pixel centres 0 .. size - 1); ``depth_mm`` (N,): along the optical axis;
    ``blur_px`` (N,): the optics' blur sigma there; ``pose``; ``intrinsics``: the true camera.
    """

    corners_px: FloatArray
    in_frame: npt.NDArray[np.bool_]
    depth_mm: FloatArray
    blur_px: FloatArray
    pose: TargetPose
    intrinsics: CameraIntrinsics


def _defocus(image: FloatArray, sigma_px: FloatArray) -> FloatArray:
    """``image`` defocused: each pixel's light spread by a Gaussian of its own ``sigma_px``.

    Each scene point's light spreads by the blur of its own depth (a scattering model: a tilted target's
    nearer side blurs into the farther one as a lens does). The image is split between a stack of blur
    levels by linear interpolation in sigma, pixel by pixel, and each part blurred by its level.
    """
    top = float(np.max(sigma_px))
    if top < 0.05:
        return image
    if top > _BLUR_LEVELS[-1]:
        raise ValueError(f"defocus blur of {top:.0f} px is beyond the renderer's {_BLUR_LEVELS[-1]:.0f} px")
    levels = _BLUR_LEVELS[: int(np.searchsorted(_BLUR_LEVELS, top)) + 1]
    below = np.zeros(sigma_px.shape, dtype=np.int8)  # levels <= sigma (searchsorted's "right" side)
    for level in levels:
        below += sigma_px >= level
    idx = np.clip(below - 1, 0, len(levels) - 2)
    lo, hi = levels.take(idx), levels.take(idx + 1)
    frac = np.clip((sigma_px - lo) / (hi - lo), 0.0, 1.0)
    # each pixel's light: 1 - frac of it on its lower level, frac on the next
    on_lower, on_upper = (image * (1.0 - frac)).astype(np.float32), (image * frac).astype(np.float32)
    nothing = np.float32(0.0)
    out = np.zeros(image.shape, dtype=np.float64)
    present = np.bincount(idx.ravel(), minlength=len(levels)) > 0  # the pixels' lower levels
    for k, s in enumerate(levels):
        if not (present[k] or (k > 0 and present[k - 1])):
            continue  # no pixel's light on this level
        part = np.where(idx == k, on_lower, np.where(idx == k - 1, on_upper, nothing))
        if s > 0.0:
            part = cv2.GaussianBlur(part, (0, 0), float(s), borderType=cv2.BORDER_REFLECT)
        out += part
    return out


def sensor_readout(
    clean: Float32Array, preset: NoisePreset, rng: np.random.Generator
) -> npt.NDArray[np.uint8]:
    """The 8-bit frame the sensor gives for the noise-free grey levels ``clean`` (DN).

    Read and shot noise (variance ``read^2 + gain * signal``), rounding, clipping to 0-255, then salt and
    pepper: the noise model of ``sim.artifact.render``, in the same order.
    """
    shape = clean.shape
    variance = np.float32(preset.read_noise_dn**2) + np.float32(preset.shot_noise_gain_dn_per_e) * np.maximum(
        clean, 0
    )
    noisy = clean + np.sqrt(variance) * rng.standard_normal(shape, dtype=np.float32)
    image = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    if preset.salt_pepper_fraction > 0:
        flat = image.reshape(-1)
        count = int(rng.binomial(flat.size, preset.salt_pepper_fraction))
        flat[rng.integers(0, flat.size, count)] = rng.integers(0, 2, count, dtype=np.uint8) * np.uint8(255)
    return image


def render_target(
    pose: TargetPose,
    *,
    intrinsics: CameraIntrinsics,
    target: CharucoTarget = STANDARD_TARGET,
    preset: NoisePreset | str = "nominal",
    focus_mm: float = 68.0,
    defocus_px_per_mm: float = 20.0,
    rng: np.random.Generator,
) -> tuple[npt.NDArray[np.uint8], TargetTruth]:
    """Render one 8-bit frame of the calibration target, with its ground truth.

    Parameters
    ----------
    pose : TargetPose
        The target's frame in the camera's (mm).
    intrinsics : CameraIntrinsics
        The true camera (its ``image_size`` is the frame's).
    target : CharucoTarget
        The target; its markers and margins must be whole numbers of marker bits.
    preset : NoisePreset or str
        Blur (in focus), grey levels (black: ``paint_level_dn``, white: ``land_level_dn``), noise and
        vignetting.
    focus_mm : float
        Distance of the focal plane along the optical axis, mm (the working distance).
    defocus_px_per_mm : float
        Growth of the blur sigma with the distance from the focal plane, px per mm (``sim.world``'s).
    rng : numpy.random.Generator
        The frame's noise.

    Returns
    -------
    image : numpy.ndarray, (height, width) uint8
    truth : TargetTruth
    """
    if intrinsics.image_size is None:
        raise ValueError("the true camera needs its image size")
    if not (
        np.isfinite(focus_mm) and focus_mm > 0 and np.isfinite(defocus_px_per_mm) and defocus_px_per_mm >= 0
    ):
        raise ValueError("focus_mm must be > 0 and defocus_px_per_mm >= 0")
    n = target.cells_per_square()
    if n is None:
        raise ValueError(
            "the twin renders targets whose markers and margins are whole numbers of marker bits"
        )
    p = get_preset(preset) if isinstance(preset, str) else preset
    width, height = intrinsics.image_size
    shape = (height, width)
    reflect, depth = scene(
        pixel_rays(intrinsics, shape),
        pose.rotation,
        pose.translation_mm,
        target_face(target, n),
        target.square_mm / n,
        p.blur_sigma_px,
    )
    reflect = _defocus(reflect, defocus_px_per_mm * np.abs(depth - focus_mm))
    clean = (p.paint_level_dn + reflect * (p.land_level_dn - p.paint_level_dn)).astype(np.float32)
    clean *= cached_vignetting(shape, float(p.vignetting))
    image = sensor_readout(clean, p, rng)
    return image, _truth(target, pose, intrinsics, focus_mm, p.blur_sigma_px, defocus_px_per_mm)


def _truth(
    target: CharucoTarget,
    pose: TargetPose,
    intrinsics: CameraIntrinsics,
    focus_mm: float,
    blur_px: float,
    defocus_px_per_mm: float,
) -> TargetTruth:
    pts = target.corners_mm()
    cam = pts @ pose.rotation.T + pose.translation_mm
    corners, _ = cv2.projectPoints(
        pts, pose.rvec, pose.translation_mm, intrinsics.camera_matrix, intrinsics.dist_coeffs
    )
    corners = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    corners[cam[:, 2] <= 0] = np.nan
    assert intrinsics.image_size is not None
    w, h = intrinsics.image_size
    with np.errstate(invalid="ignore"):
        inside = (
            (corners[:, 0] >= 0) & (corners[:, 0] <= w - 1) & (corners[:, 1] >= 0) & (corners[:, 1] <= h - 1)
        )
    blur = np.hypot(blur_px, defocus_px_per_mm * (cam[:, 2] - focus_mm))
    for arr in (corners, inside, cam, blur):
        arr.setflags(write=False)
    return TargetTruth(corners, inside, cam[:, 2].copy(), blur, pose, intrinsics)
