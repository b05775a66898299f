"""Rendered frames: levels, features fixed to the artifact, noise fresh per frame."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sim.artifact import ArtifactSpec, pose_for_center_px, render, render_ideal
from sim.presets import PRESETS

NOMINAL = PRESETS["nominal"]
QUIET = replace(  # nominal surface, no noise, no vignetting: the frame is a function of the pose only
    NOMINAL, name="quiet", read_noise_dn=0.0, shot_noise_gain_dn_per_e=0.0, vignetting=0.0
)
BARE = replace(QUIET, name="bare", texture_rms_dn=0.0, glints_per_mm=0.0, scratches_per_mm2=0.0)
POSE = pose_for_center_px(321.0, 243.0, rotation_deg=2.5, tilt_x_deg=0.3)


def _frame(pose=POSE, preset=QUIET, seed: int = 0, **kw):
    return render(pose, preset=preset, rng=np.random.default_rng(seed), **kw)[0].astype(np.float64)


def test_render_gives_an_8bit_frame_with_its_truth() -> None:
    image, truth = render(POSE, rng=np.random.default_rng(1))
    assert image.dtype == np.uint8
    assert image.shape == (480, 640)
    land = render_ideal(POSE, blur_sigma_px=1.0)
    assert 185 < np.median(image[land == 1.0]) < 215
    assert 30 < np.median(image[land == 0.0]) < 50
    assert truth.center_px == pytest.approx((321.0, 243.0))


def test_same_seed_same_frame_and_new_seed_new_noise() -> None:
    a = _frame(preset="nominal", seed=5)
    assert np.array_equal(a, _frame(preset="nominal", seed=5))
    b = _frame(preset="nominal", seed=6)
    land = render_ideal(POSE, blur_sigma_px=1.0) == 1.0
    noise = (a - b)[land].std() / np.sqrt(2)
    assert noise == pytest.approx(np.hypot(NOMINAL.noise_dn(205 * 0.97), 0.29), rel=0.15)


def test_texture_moves_with_the_artifact() -> None:
    pose = pose_for_center_px(300.0, 240.0)
    a = _frame(pose)
    b = _frame(pose.displaced(0.07, -0.03))  # 7 px right, 3 px up
    diff = np.abs(b[20:-20, 27:-20] - a[23:-17, 20:-27])
    assert diff.max() <= 1
    assert (diff > 0).mean() < 1e-4
    assert not np.array_equal(b, a)
    assert (a - _frame(pose, BARE)).std() > 0.3  # there is texture to follow


def test_glints_lie_in_the_paint_and_scratches_on_the_lands() -> None:
    land = render_ideal(POSE, blur_sigma_px=1.0)
    glints = _frame(preset=replace(BARE, glints_per_mm=3.0)) - _frame(preset=BARE)
    assert glints.max() > 30
    assert (glints[land == 1.0] == 0).all()
    scratched = replace(BARE, scratches_per_mm2=0.5, scratch_depth_dn=40.0, scratch_width_max_mm=0.015)
    scratches = _frame(preset=scratched) - _frame(preset=BARE)
    assert scratches.min() < -5
    assert (scratches[land == 0.0] == 0).all()
    assert scratches.max() <= 0
    hard_glints = _frame(preset=replace(PRESETS["hard"], read_noise_dn=0.0, shot_noise_gain_dn_per_e=0.0))
    assert (hard_glints[land == 0.0] > 150).sum() > 20  # the hard preset's glints are bright


def test_features_are_fixed_to_the_artifact_seed() -> None:
    preset = replace(BARE, texture_rms_dn=4.0)
    a = _frame(preset=preset)
    assert np.array_equal(a, _frame(preset=preset))
    assert not np.array_equal(a, _frame(preset=preset, artifact=ArtifactSpec(texture_seed=1)))


def test_vignetting_darkens_the_corners() -> None:
    pose = pose_for_center_px(100.0, 100.0)
    image = _frame(pose, replace(BARE, vignetting=0.3))
    assert image[479, 639] == pytest.approx(205 * 0.7, abs=1.0)
    assert image[240, 320] == pytest.approx(205, abs=1.0)


def test_salt_and_pepper_hits_the_requested_fraction() -> None:
    preset = replace(BARE, salt_pepper_fraction=0.004)
    clean, noisy = _frame(preset=BARE), _frame(preset=preset, seed=3)
    hit = clean != noisy
    assert hit.mean() == pytest.approx(0.004, rel=0.15)
    assert set(np.unique(noisy[hit])) <= {0.0, 255.0}


def test_flecks_lie_in_the_paint_and_specks_anywhere_both_bright() -> None:
    land = render_ideal(POSE, blur_sigma_px=1.0)
    specks = PRESETS["hard-specks"]
    flecked = replace(
        BARE,
        flecks_per_mm=specks.flecks_per_mm,
        fleck_cluster_mm=specks.fleck_cluster_mm,
        fleck_sigma_min_mm=specks.fleck_sigma_min_mm,
        fleck_sigma_max_mm=specks.fleck_sigma_max_mm,
        fleck_peak_min_dn=specks.fleck_peak_min_dn,
        fleck_peak_max_dn=specks.fleck_peak_max_dn,
        fleck_glint_peak_dn=specks.fleck_glint_peak_dn,
    )
    flecks = _frame(preset=flecked) - _frame(preset=BARE)
    assert (flecks[land == 1.0] == 0).all()  # chips in the paint only
    assert (flecks[land == 0.0] >= 150).sum() > 20  # their glints are bright (up to saturation)
    assert flecks.min() >= 0
    dusty = replace(
        BARE,
        specks_per_mm2=specks.specks_per_mm2,
        speck_sigma_min_mm=specks.speck_sigma_min_mm,
        speck_sigma_max_mm=specks.speck_sigma_max_mm,
        speck_peak_min_dn=specks.speck_peak_min_dn,
        speck_peak_max_dn=specks.speck_peak_max_dn,
    )
    dust = _frame(preset=dusty) - _frame(preset=BARE)
    assert (dust[land == 1.0] > 30).sum() > 20  # on the lands
    assert (dust[land == 0.0] > 100).sum() > 5  # and in the grooves
    assert dust.min() >= 0


def test_flecks_and_specks_move_with_the_artifact() -> None:
    from sim._render_specks import fleck_points, speck_points

    preset = replace(
        PRESETS["hard-specks"],
        read_noise_dn=0.0,
        shot_noise_gain_dn_per_e=0.0,
        salt_pepper_fraction=0.0,
        vignetting=0.0,
        texture_rms_dn=0.0,
        scratches_per_mm2=0.0,
        glints_per_mm=0.0,
    )
    pose = pose_for_center_px(300.0, 240.0)
    a = _frame(pose, preset)
    b = _frame(pose.displaced(0.07, -0.03), preset)  # 7 px right, 3 px up
    diff = np.abs(b[20:-20, 27:-20] - a[23:-17, 20:-27])
    assert diff.max() <= 1
    assert not np.array_equal(a, b)
    h = render(pose, preset=preset, rng=np.random.default_rng(0))[1].homography
    moved = render(pose.displaced(0.07, -0.03), preset=preset, rng=np.random.default_rng(0))[1].homography
    for points in (
        lambda hh: fleck_points(
            hh, texture_seed=0, groove_width_mm=ArtifactSpec().groove_width_mm, preset=preset
        ),
        lambda hh: speck_points(hh, texture_seed=0, preset=preset),
    ):
        assert len(points(h)) > 100
        shift = points(moved) - points(h)
        np.testing.assert_allclose(shift, np.broadcast_to([7.0, -3.0], shift.shape), atol=0.05)


def test_the_benchmark_presets_have_no_flecks_or_specks() -> None:
    # their frames are those rendered before flecks and specks existed (the benchmark sets unchanged)
    for name in ("nominal", "hard"):
        assert PRESETS[name].flecks_per_mm == 0
        assert PRESETS[name].specks_per_mm2 == 0
