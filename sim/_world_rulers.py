"""What the simulated world's camera sees of a ruler in its cell (``sim.world`` calls it).

The ruler's twin (``sim.ruler.render_ruler``) renders the pattern through the world's true camera and
preset (the defocus of the view's depth included), with the ruler's own surface (dust, gradient,
scratches, fixed to the ruler by its index); beyond the ruler's glass (``sim.cell_rulers``) the frame
shows the world's background.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from sim._render_camera import CameraSpec, Pose
from sim.cell_rulers import RULER_LENGTH_MM, SUBSTRATE_END_MM, SUBSTRATE_WIDTH_MM, ruler_view
from sim.presets import NoisePreset
from sim.ruler import RulerTruth, render_ruler

FloatArray = npt.NDArray[np.float64]
Image = npt.NDArray[np.uint8]


TABLE_RULER_S_MM = 125.0
"""Where along a ruler on the X-Y table (``WorldSpec.table_artifact = "ruler"``) the optical axis meets
it at the reference pose and table (0, 0): its middle, so that a validation's pattern stays on it."""


def table_ruler_frame(artifact_frame: FloatArray, s_mm: float = TABLE_RULER_S_MM) -> FloatArray:
    """The 4x4 frame (base frame) of a ruler laid on the X-Y table in place of the crossed artifact: its
    ``s`` along the artifact's u, ``t`` along v, ``n`` into the table as the artifact's, and its point
    ``s_mm`` on the axis where the crossing would be (``artifact_frame``, the table at (0, 0))."""
    F = np.array(artifact_frame, dtype=np.float64)
    F[:3, 3] -= F[:3, 0] * s_mm
    return F


def _off_glass(homography: FloatArray, shape: tuple[int, int]) -> npt.NDArray[np.bool_] | None:
    """Pixels whose ray meets the ruler's plane beyond its glass; None when the whole frame is on it."""
    g = np.linalg.inv(homography)
    h, w = shape

    def st(xs: FloatArray, ys: FloatArray) -> tuple[FloatArray, FloatArray]:
        den = g[2, 0] * xs + g[2, 1] * ys + g[2, 2]
        return (g[0, 0] * xs + g[0, 1] * ys + g[0, 2]) / den, (g[1, 0] * xs + g[1, 1] * ys + g[1, 2]) / den

    def outside(s: FloatArray, t: FloatArray) -> npt.NDArray[np.bool_]:
        half = SUBSTRATE_WIDTH_MM / 2.0
        return np.asarray(
            (s < -SUBSTRATE_END_MM) | (s > RULER_LENGTH_MM + SUBSTRATE_END_MM) | (np.abs(t) > half)
        )

    corners = np.array([0.0, w - 1.0, 0.0, w - 1.0]), np.array([0.0, 0.0, h - 1.0, h - 1.0])
    if not outside(*st(*corners)).any():
        return None  # the glass is convex: the frame's four corners on it put the whole frame on it
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    return outside(*st(xs, ys))


def render_ruler_view(
    ruler_in_camera: FloatArray,
    *,
    camera: CameraSpec,
    preset_for: Callable[[Pose], NoisePreset],
    background: Callable[[], Image],
    texture_seed: int,
    rng: np.random.Generator,
) -> tuple[Image, RulerTruth] | None:
    """The frame of a ruler (its 4x4 frame in the camera's) and its truth; None when the ruler is seen at
    a grazing angle (45 deg or more from square: beyond the twin's model, and out of focus anyway).

    ``preset_for`` gives the preset for the view's pose (the world's: defocus and exposure);
    ``background`` a frame of what lies beyond the glass.
    """
    R = ruler_in_camera[:3, :3]
    if R[2, 2] <= np.cos(np.radians(45.0)) or ruler_in_camera[2, 3] <= 1.0:
        return None
    pose, anchor = ruler_view(ruler_in_camera, camera.working_distance_mm)
    image, truth = render_ruler(
        pose, anchor_mm=anchor, preset=preset_for(pose), camera=camera, texture_seed=texture_seed, rng=rng
    )
    beyond = _off_glass(truth.homography, camera.shape)
    if beyond is not None:
        image = np.where(beyond, background(), image)
    return image, truth


__all__ = ["TABLE_RULER_S_MM", "render_ruler_view", "table_ruler_frame"]
