"""What a camera pose predicts a ruler frame reads: the ruler's ``(s, t)`` under a pixel, the image scale
there and the distance sensor's reading (vectorised; pure geometry).

A ruler's frame in the base frame is its origin ``o`` (graduation 0 on the axis, on the top surface)
and a rotation whose columns are ``s`` (along), ``t`` (across) and ``n = s x t`` (into the ruler). The
camera is a pinhole at ``c`` with rotation ``R`` (OpenCV axes), focal length ``f`` px and principal
point ``(cx, cy)``. A pixel's ray ``d = R ((u - cx) / f, (v - cy) / f, 1)`` meets the ruler's surface
at ``P = c + lambda d``, ``lambda = n . (o - c) / n . d``; the frame reads ``s = (P - o) . s`` and
``t = (P - o) . t`` there. The image scale ``measure_ruler`` reports is ``1 / |grad s|`` (px per mm of
``s``, across the graduations) at that pixel, whose gradient follows from ``dP/du = lambda (a_u - d
(n . a_u) / (n . d))``, ``a_u = R e_x / f`` (and likewise for ``v``). The sensor's reading is the
distance along its beam (the mount's +z, from its origin) to the surface, as for a crossing's plate.
"""

from __future__ import annotations

import numpy as np

from station.calibration._observations import FloatArray


def small_rotations(angles_rad: FloatArray) -> FloatArray:
    """``Rx(a) Ry(b) Rz(c)`` for each row ``(a, b, c)`` of ``angles_rad`` (R, 3) -> (R, 3, 3)."""
    a, b, c = angles_rad[:, 0], angles_rad[:, 1], angles_rad[:, 2]
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    out = np.empty((len(angles_rad), 3, 3))
    out[:, 0, 0] = cb * cc
    out[:, 0, 1] = -cb * sc
    out[:, 0, 2] = sb
    out[:, 1, 0] = sa * sb * cc + ca * sc
    out[:, 1, 1] = -sa * sb * sc + ca * cc
    out[:, 1, 2] = -sa * cb
    out[:, 2, 0] = -ca * sb * cc + sa * sc
    out[:, 2, 1] = ca * sb * sc + sa * cc
    out[:, 2, 2] = ca * cb
    return out


def predict_rulers(
    cameras: FloatArray,
    origins: FloatArray,
    rotations: FloatArray,
    reference_px: FloatArray,
    *,
    focal_px: float,
    principal_px: tuple[float, float],
    mount: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Predicted ``(s, t)`` (n, 2) mm, image scale (n,) px/mm and sensor reading (n,) mm of n frames.

    Parameters
    ----------
    cameras
        Camera poses (n, 4, 4), base frame.
    origins, rotations
        Each frame's ruler: origin (n, 3) and rotation (n, 3, 3), columns ``s, t, n``.
    reference_px
        The pixel (n, 2) whose ruler coordinates and scale are predicted.
    focal_px, principal_px
        The pinhole's focal length and principal point (px).
    mount
        The distance sensor's 4x4 pose in the camera frame (beam along its +z).

    Notes
    -----
    A ray parallel to the surface, or a surface behind the camera, gives non-finite values (the fit
    turns them into large residuals).
    """
    R = cameras[:, :3, :3]
    c = cameras[:, :3, 3]
    s_axis, t_axis, normal = rotations[:, :, 0], rotations[:, :, 1], rotations[:, :, 2]
    ray_c = np.column_stack(
        [
            (reference_px[:, 0] - principal_px[0]) / focal_px,
            (reference_px[:, 1] - principal_px[1]) / focal_px,
            np.ones(len(reference_px)),
        ]
    )
    d = np.einsum("nij,nj->ni", R, ray_c)
    a_u = R[:, :, 0] / focal_px
    a_v = R[:, :, 1] / focal_px
    with np.errstate(divide="ignore", invalid="ignore"):
        n_d = np.einsum("ni,ni->n", normal, d)
        lam = np.einsum("ni,ni->n", normal, origins - c) / n_d
        rel = c + lam[:, None] * d - origins
        st = np.column_stack([np.einsum("ni,ni->n", rel, s_axis), np.einsum("ni,ni->n", rel, t_axis)])
        dP_du = lam[:, None] * (a_u - d * (np.einsum("ni,ni->n", normal, a_u) / n_d)[:, None])
        dP_dv = lam[:, None] * (a_v - d * (np.einsum("ni,ni->n", normal, a_v) / n_d)[:, None])
        grad = np.hypot(np.einsum("ni,ni->n", dP_du, s_axis), np.einsum("ni,ni->n", dP_dv, s_axis))
        scale = 1.0 / grad
        origin = np.einsum("nij,j->ni", R, mount[:3, 3]) + c
        beam = np.einsum("nij,j->ni", R, mount[:3, 2])
        z = np.einsum("ni,ni->n", normal, origins - origin) / np.einsum("ni,ni->n", normal, beam)
    return st, scale, z


__all__ = ["predict_rulers", "small_rotations"]
