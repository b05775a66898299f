"""Issue 19, finding 5 and item 7: a valid cross is never refused as ``incomplete_cross``.

The cross check reads where a groove ends from its two walls over a stretch of steps, so that bright
specks, chips in the paint and their glints (the ``hard-specks`` preset) near the frame's border do
not end an arm there; a T-junction (an arm of bare land) stays refused, also on that preset and when
its missing arm is short. ``tests/security/test_hostile_cross.py`` holds the T-junctions and two-cross frames
of issue 13, which must stay refused too.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim._render_specks import fleck_points, speck_points
from sim.artifact import ArtifactSpec, Truth, pose_for_center_px, render, truth_for
from sim.imageset import random_poses
from sim.presets import get_preset
from station.vision import (
    EDGES,
    IncompleteCrossError,
    MeasurementError,
    MeasureParams,
    check_single_cross,
    measure,
)
from station.vision._geometry import check_cross
from tests.hostile import cross, t_junction

PRESET = "hard-specks"
#: A feature this close to the frame's border (px) is "near the border".
NEAR_BORDER_PX = 24.0
#: Frames of the set, and the bright features near the border on the arms each must show.
SET_SIZE = 240
MIN_BORDER_FEATURES = 3
#: A centre measured on these frames is within this of the truth (px): precise mode (the benchmark's
#: hard maximum is 0.044 px; 0.063 px here) and the seed's method (0.151 px; 0.30 px here).
CENTRE_BOUND_PX = {"precise": 0.15, "paper": 0.5}


def border_features(truth: Truth, arm: str | None = None) -> int:
    """How many chips and specks image on an arm (``arm``, or any) within ``NEAR_BORDER_PX`` of the
    frame's border: inside one groove's band, beyond the other groove."""
    preset, artifact = get_preset(PRESET), ArtifactSpec()
    points = np.vstack(
        [
            fleck_points(
                truth.homography,
                texture_seed=artifact.texture_seed,
                groove_width_mm=artifact.groove_width_mm,
                preset=preset,
            ),
            speck_points(truth.homography, texture_seed=artifact.texture_seed, preset=preset),
        ]
    )
    x, y = points[:, 0], points[:, 1]
    inside = (x >= 0) & (y >= 0) & (x <= 639) & (y <= 479)
    near = np.minimum.reduce([x, y, 639 - x, 479 - y]) < NEAR_BORDER_PX
    top, bottom, left, right = (line[0] * x + line[1] * y - line[2] for line in np.asarray(truth.lines))
    in_horizontal, in_vertical = (top >= 0) & (bottom <= 0), (left >= 0) & (right <= 0)
    on_arm = {  # the lines' normals point toward increasing u (left, right) and v (top, bottom)
        "right": in_horizontal & (right > 0),
        "left": in_horizontal & (left < 0),
        "lower": in_vertical & (bottom > 0),
        "upper": in_vertical & (top < 0),
    }
    arms = [on_arm[arm]] if arm is not None else list(on_arm.values())
    return int(sum((a & inside & near).sum() for a in arms))


def test_finding_5_a_whole_cross_with_specks_by_the_border_is_measured() -> None:
    # the right arm runs to the frame's edge through a damaged spot of the paint: chips with
    # saturated glints and dust specks in its last 24 px; today: "the right arm ends 280 px from the
    # crossing" (the issue's frame: 312 px)
    image, truth = cross(338.0, 280.0, 0.0, preset=PRESET, seed=0)
    assert border_features(truth, "right") >= 4
    right_end = image[240:320, 615:]  # the groove's end at the border: bright specks in the paint
    assert (right_end > 200).sum() >= 10
    m = measure(image, MeasureParams(mode="precise"))
    assert np.hypot(*(np.asarray(m.center_px) - truth.center_px)) < CENTRE_BOUND_PX["precise"]
    # the seed's method fits its edges through fewer specks: it may refuse, but not this way
    code = "measured"
    try:
        m = measure(image, MeasureParams(mode="paper"))
    except MeasurementError as exc:
        code = exc.code
    if code == "measured":
        assert np.hypot(*(np.asarray(m.center_px) - truth.center_px)) < CENTRE_BOUND_PX["paper"]
    assert code not in {"incomplete_cross", "multiple_crossings"}


def _specks_set() -> list[tuple[np.ndarray, Truth]]:
    """``SET_SIZE`` frames of the hard-specks preset, each with bright features by the border on its
    arms (random poses inside the contract's envelope, turned up to 30 deg, tilted up to 1 deg)."""
    frames: list[tuple[np.ndarray, Truth]] = []
    for k, pose in enumerate(random_poses(2 * SET_SIZE, seed=19, max_rotation_deg=30.0)):
        if border_features(truth_for(pose)) < MIN_BORDER_FEATURES:
            continue
        image, truth = render(pose, preset=PRESET, rng=np.random.default_rng(k))
        frames.append((image, truth))
        if len(frames) == SET_SIZE:
            return frames
    raise AssertionError(f"only {len(frames)} frames show features by the border: draw more poses")


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_no_whole_cross_with_specks_by_the_border_is_an_incomplete_cross() -> None:
    refused: dict[str, list[str]] = {"precise": [], "paper": []}
    errors: dict[str, list[float]] = {"precise": [], "paper": []}
    for k, (image, truth) in enumerate(_specks_set()):
        for mode in ("precise", "paper"):
            try:
                m = measure(image, MeasureParams(mode=mode))
            except MeasurementError as exc:
                refused[mode].append(f"{k} {exc.code}: {exc}")
                continue
            errors[mode].append(float(np.hypot(*(np.asarray(m.center_px) - truth.center_px))))
    sanity = [
        r for rs in refused.values() for r in rs if "incomplete_cross" in r or "multiple_crossings" in r
    ]
    assert not sanity, sanity
    # precise mode measures (nearly) all of them; every number reported, in either mode, is right
    assert len(refused["precise"]) <= 2, refused["precise"]
    for mode, errs in errors.items():
        assert max(errs) < CENTRE_BOUND_PX[mode], mode


def _check(image: np.ndarray, truth: Truth) -> None:
    """The cross check alone, on the true edges (so that every frame reaches it)."""
    lines = dict(zip(EDGES, (tuple(line) for line in np.asarray(truth.lines)), strict=True))
    corners = np.asarray(truth.corners_px, dtype=np.float64)
    _, widths = check_cross(lines, corners, image.shape, max_rotation_deg=40.0)
    check_single_cross(image, lines, corners, widths)


ARMS = ["left", "right", "upper", "lower"]
T_POSES = [(330.0, 245.0, 6.0), (300.0, 250.0, -8.0), (250.0, 300.0, 25.0)]


@pytest.mark.parametrize("preset", ["hard", PRESET])
@pytest.mark.parametrize("pose", T_POSES)
@pytest.mark.parametrize("missing", ARMS)
def test_a_t_junction_stays_refused(missing: str, pose: tuple[float, float, float], preset: str) -> None:
    image = t_junction(*pose, missing, preset=preset)
    truth = truth_for(pose_for_center_px(pose[0], pose[1], rotation_deg=pose[2]))
    with pytest.raises(IncompleteCrossError, match=f"only three arms.*the {missing} arm ends"):
        _check(image, truth)
    for mode in ("precise", "paper"):  # the whole measurement: refused, by this check when it is reached
        with pytest.raises(MeasurementError) as info:
            measure(image, MeasureParams(mode=mode))
        assert info.value.code in {"incomplete_cross", "edges_not_found"}, (mode, info.value)


@pytest.mark.parametrize("missing", ARMS)
def test_an_arm_that_ends_30_px_before_the_border_is_missing(missing: str) -> None:
    # a stub: the groove runs on past the crossing but stops 30 px before the frame's border, where
    # chips and specks could hide nothing: no groove, not even a broken one, continues to the border
    cx, cy = 320.0, 240.0
    half_width = 0.5 * ArtifactSpec().groove_width_mm * 100.0  # px at the focal plane
    room = {"left": cx, "right": 639.0 - cx, "upper": cy, "lower": 479.0 - cy}[missing] - half_width
    image = t_junction(cx, cy, 0.0, missing, preset=PRESET, ends_px=room - 30.0)
    truth = truth_for(pose_for_center_px(cx, cy))
    with pytest.raises(IncompleteCrossError, match=f"the {missing} arm ends"):
        _check(image, truth)
    # and 6 px before the border, too close to tell from the border itself: a whole cross
    _check(t_junction(cx, cy, 0.0, missing, preset=PRESET, ends_px=room - 6.0), truth)
