"""Rendered test images with ground truth (the simulator is the reference, sim/artifact.py)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypedDict, Unpack

import numpy as np
import pytest

from sim.artifact import Truth, pose_for_center_px, render
from sim.imageset import render_random_set, render_validation_set

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


#: Paper mode's pinned results on the benchmark's image sets (``test_paper_reference``).
PAPER_REFERENCE = Path(__file__).parent / "data" / "paper_reference.json"


def paper_reference() -> dict[str, Any]:
    doc: dict[str, Any] = json.loads(PAPER_REFERENCE.read_text())
    return doc


@pytest.fixture(scope="session")
def bench_sets(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The benchmark's image sets (random poses and the validation pattern, nominal and hard presets),
    rendered exactly as ``make bench`` renders them."""
    root = tmp_path_factory.mktemp("bench-sets")
    for name, spec in paper_reference()["sets"].items():
        if spec["kind"] == "random":
            render_random_set(root / name, preset=spec["preset"], count=spec["count"], seed=spec["seed"])
        else:
            render_validation_set(root / name, preset=spec["preset"], seed=spec["seed"])
    return root
