"""The simulated camera's true lens: intrinsics that differ from the nominal, drawn from a seed.

The nominal camera (``sim.artifact.CameraSpec``) is an ideal pinhole: focal length ``px_per_mm x
working_distance_mm``, principal point at the image centre, no distortion. A real lens and sensor differ:
the focal length from the data sheet's by a percent or two, the principal point from the image centre by
tens of pixels (the sensor's placement), and the lens distorts, radially and, when its elements are
decentred, tangentially. :func:`true_intrinsics` draws such a camera in OpenCV's model, which the
station's camera calibration must then find (``station.camcal``).
"""

from __future__ import annotations

import numpy as np

from sim._render_camera import CameraSpec
from station.camera_model import CameraIntrinsics

__all__ = ["nominal_intrinsics", "true_intrinsics"]


def nominal_intrinsics(camera: CameraSpec = CameraSpec()) -> CameraIntrinsics:  # noqa: B008 - frozen
    """The ideal pinhole of ``camera`` as a camera model (what the station assumes before calibrating)."""
    return CameraIntrinsics(camera.matrix(), np.zeros(5), (camera.width, camera.height))


def true_intrinsics(
    seed: int,
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
    *,
    focal_rel: float = 0.02,
    aspect_rel: float = 0.002,
    principal_px: float = 20.0,
    radial_px: float = 2.0,
    tangential_px: float = 0.0,
) -> CameraIntrinsics:
    """A camera that differs from ``camera``'s nominal pinhole, drawn uniformly from ``seed``.

    Parameters
    ----------
    seed : int
        Seeds every draw (the same seed gives the same camera).
    camera : CameraSpec
        The nominal camera (image size, focal length, centre).
    focal_rel : float
        ``fx`` within ``+/- focal_rel`` (relative) of the nominal focal length.
    aspect_rel : float
        ``fy`` within ``+/- aspect_rel`` of ``fx`` (non-square pixels, a frame grabber's sampling).
    principal_px : float
        ``cx``, ``cy`` each within ``+/- principal_px`` of the image centre, px.
    radial_px : float
        ``k1`` such that the image's corner moves by up to ``+/- radial_px`` px (barrel or pincushion).
    tangential_px : float
        ``p1``, ``p2`` such that each moves the image's corner by up to ``+/- tangential_px`` px; 0 (the
        default): no tangential distortion.

    Returns
    -------
    CameraIntrinsics
        With ``dist_coeffs = (k1, 0, p1, p2, 0)`` and the camera's image size; ``source`` records the
        seed and the ranges.
    """
    for name, value in (
        ("focal_rel", focal_rel),
        ("aspect_rel", aspect_rel),
        ("principal_px", principal_px),
        ("radial_px", radial_px),
        ("tangential_px", tangential_px),
    ):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be a finite value >= 0, got {value!r}")
    if focal_rel >= 0.5 or aspect_rel >= 0.1:
        raise ValueError("focal_rel must be below 0.5 and aspect_rel below 0.1")
    rng = np.random.default_rng([int(seed), 0x1E45])
    u = rng.uniform(-1.0, 1.0, 7)
    fx = camera.focal_px * (1.0 + focal_rel * u[0])
    fy = fx * (1.0 + aspect_rel * u[1])
    cx0, cy0 = camera.principal_point
    cx, cy = cx0 + principal_px * u[2], cy0 + principal_px * u[3]
    # At the corner, radius r_px from the centre (r = r_px / f normalised), k1 r^2 moves it k1 r^3 f px;
    # p1 (p2) moves it by up to about 3 p r^2 f px.
    r_px = float(np.hypot(cx0 + 0.5, cy0 + 0.5))
    r = r_px / fx
    k1 = radial_px * u[4] / (r**3 * fx)
    p1, p2 = (tangential_px * u[5:7] / (3.0 * r * r * fx)).tolist()
    return CameraIntrinsics(
        np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]),
        np.array([k1, 0.0, p1, p2, 0.0]),
        (camera.width, camera.height),
        source={
            "sim_seed": int(seed),
            "focal_rel": focal_rel,
            "aspect_rel": aspect_rel,
            "principal_px": principal_px,
            "radial_px": radial_px,
            "tangential_px": tangential_px,
        },
    )
