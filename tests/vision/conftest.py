"""Rendered test images with ground truth (the simulator is the reference, sim/artifact.py)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypedDict, Unpack

import numpy as np
import pytest

from sim.artifact import Truth, pose_for_center_px, render

Render = Callable[..., tuple[np.ndarray, Truth]]


class PoseOptions(TypedDict, total=False):
    """The keyword arguments ``pose_for_center_px`` takes besides the camera."""

    rotation_deg: float
    tilt_x_deg: float
    tilt_y_deg: float
    z_mm: float


def random_cases(n: int, seed: int, *, max_rotation: float = 10.0) -> list[dict[str, float]]:
    """Random poses inside the issue's envelope: crossing with corners >= 40 px inside the frame."""
    rng = np.random.default_rng(seed)
    return [
        {
            "cx": float(rng.uniform(130, 510)),
            "cy": float(rng.uniform(130, 350)),
            "rotation_deg": float(rng.uniform(-max_rotation, max_rotation)),
            "tilt_x_deg": float(rng.uniform(-1, 1)),
            "tilt_y_deg": float(rng.uniform(-1, 1)),
        }
        for _ in range(n)
    ]


@pytest.fixture
def rendered() -> Render:
    def _render(
        cx: float, cy: float, *, preset: str = "nominal", seed: int = 0, **pose: Unpack[PoseOptions]
    ) -> tuple[np.ndarray, Truth]:
        return render(pose_for_center_px(cx, cy, **pose), preset=preset, rng=np.random.default_rng(seed))

    return _render
