"""Issue 13, a cross is a cross: two crosses or a T-junction fail with a specific error in both modes,
and crosses of the contract's envelope (also close to the border, where the arms are short) pass."""

from __future__ import annotations

import numpy as np
import pytest

from station.vision import MeasurementError, MeasureParams, measure
from tests.hostile import cross, t_junction, two_crosses

SANITY_CODES = {"incomplete_cross", "multiple_crossings"}


@pytest.mark.parametrize(
    ("mode", "missing", "preset", "rotation"),
    [
        ("paper", "left", "nominal", 5.0),
        ("paper", "upper", "nominal", 5.0),
        ("paper", "left", "hard", -8.0),
        ("precise", "right", "nominal", 5.0),
        ("precise", "lower", "nominal", 5.0),
        ("precise", "left", "hard", -8.0),
    ],
)
def test_a_t_junction_is_an_incomplete_cross(mode: str, missing: str, preset: str, rotation: float) -> None:
    cx, cy = (320.0, 240.0) if preset == "nominal" else (300.0, 250.0)
    image = t_junction(cx, cy, rotation, missing, preset=preset)
    with pytest.raises(MeasurementError, match="only three arms of the cross") as info:
        measure(image, MeasureParams(mode=mode))
    assert info.value.code == "incomplete_cross"
    assert f"the {missing} arm ends" in info.value.message


def test_two_crosses_in_one_frame_are_multiple_crossings() -> None:
    with pytest.raises(MeasurementError, match="more than one crossing") as info:
        measure(two_crosses((200.0, 170.0), (450.0, 330.0)), MeasureParams(mode="precise"))
    assert info.value.code == "multiple_crossings"


@pytest.mark.parametrize("mode", ["precise", "paper"])
def test_two_crosses_on_one_groove_never_give_a_number(mode: str) -> None:
    with pytest.raises(MeasurementError) as info:
        measure(two_crosses((320.0, 150.0), (320.0, 400.0)), MeasureParams(mode=mode))
    assert info.value.code in SANITY_CODES


@pytest.mark.parametrize(
    ("cx", "cy", "rotation", "preset"),
    [
        (58.0, 240.0, 0.0, "nominal"),  # the left arm is 18 px long
        (575.0, 75.0, 12.0, "hard"),  # top-right: two short arms
        (320.0, 400.0, -30.0, "nominal"),
        (330.0, 250.0, 39.0, "hard"),
        (100.0, 390.0, -20.0, "hard"),
    ],
)
def test_whole_crosses_of_the_envelope_pass_the_check(
    cx: float, cy: float, rotation: float, preset: str
) -> None:
    image, truth = cross(cx, cy, rotation, preset=preset, seed=4)
    corners = np.asarray(truth.corners_px)
    assert corners.min() >= 10
    assert corners[:, 0].max() <= 629
    assert corners[:, 1].max() <= 469
    m = measure(image, MeasureParams(mode="precise"))
    assert np.hypot(*(np.asarray(m.center_px) - truth.center_px)) < 0.1
