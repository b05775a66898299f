"""The ruler's compiled kernels (``station/vision/_ruler_*.c``) against the numpy reference.

As for the cross (``test_kernels``): the numpy code is the reference; the pass over the pixels gives
the same bins, the windows' rounds the same coefficients, and a whole measurement the same
position within 1e-9 px, on nominal and hard views, with and without a camera model.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.special import ndtr

from sim._render_camera import CameraSpec, pose_for_center_px
from sim.ruler import render_ruler
from station.vision import RulerParams, measure_ruler
from station.vision._kernels import available, kernels
from station.vision._ruler_bins import fold
from station.vision._ruler_coarse import coarse_ruler
from station.vision._ruler_correction import fit_correction
from station.vision._ruler_layout import plan
from station.vision._ruler_lens import lens_coordinates
from station.vision._ruler_phase import (
    _COSINE,
    _cosine_sums,
    _folded,
    _round,
    _template,
    template_value,
    window_phases,
    windows_from_bins,
)
from station.vision._ruler_tips import contrasts, fit_tip

pytestmark = pytest.mark.skipif(not available(), reason="the compiled kernels were not built")

TOL_PX = 1e-9
CAMERA = CameraSpec()
WITH_LENS = RulerParams(camera_matrix=CAMERA.matrix().tolist(), dist_coeffs=[-0.02, 0.001, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def views() -> list[np.ndarray]:
    out = []
    for k, (x, y, rot, preset) in enumerate(
        [(310.0, 250.0, 7.0, "nominal"), (330.0, 230.0, 101.0, "hard"), (300.0, 240.0, -140.0, "nominal")]
    ):
        pose = pose_for_center_px(x, y, rotation_deg=rot, tilt_x_deg=0.5, tilt_y_deg=-0.4)
        out.append(
            render_ruler(pose, anchor_mm=40.0 + 60 * k, preset=preset, rng=np.random.default_rng(k))[0]
        )
    return out


@pytest.mark.parametrize("step", [1, 2])
@pytest.mark.parametrize("lens", [False, True])
def test_the_pass_over_the_pixels_gives_the_same_bins(views: list[np.ndarray], step: int, lens: bool) -> None:
    params = WITH_LENS if lens else RulerParams()
    for image in views:
        coarse = coarse_ruler(image, params.ruler, min_periods=5)
        layout = plan(coarse.frame, coarse.period_px, params, image.shape, full=True)
        coords, _ = lens_coordinates(params.camera_matrix, params.dist_coeffs, image.shape)
        with kernels("numpy"):
            ref = fold(image, coarse.frame, layout.strips, coords, step=step)
        with kernels("c"):
            got = fold(image, coarse.frame, layout.strips, coords, step=step)
        assert ref[:, 0].sum() > 10_000
        assert_array_equal(got[:, 0], ref[:, 0])
        assert_allclose(got, ref, rtol=1e-12, atol=1e-9)


def test_the_template_is_read_the_same_anywhere() -> None:
    rng = np.random.default_rng(5)
    grid = np.cos(2 * np.pi * np.arange(4096) / 4096) + 0.1 * np.cos(6 * np.pi * np.arange(4096) / 4096)
    phase = np.concatenate([rng.uniform(-40.0, 40.0, 5000), [0.0, 0.5, -1.0, 1.0 - 1e-17, 3.999999999999]])
    phase = phase.reshape(5, -1)  # any shape
    with kernels("numpy"):
        ref = template_value(grid, phase)
    with kernels("c"):
        got = template_value(grid, phase)
    assert ref[0].shape == got[0].shape == phase.shape
    assert_array_equal(got[0], ref[0])
    assert_array_equal(got[1], ref[1])
    assert np.ptp(ref[0]) > 2.0


def test_the_bins_make_the_same_windows(views: list[np.ndarray]) -> None:
    params = RulerParams()
    empty = 0
    for image in views:
        coarse = coarse_ruler(image, params.ruler, min_periods=5)
        layout = plan(coarse.frame, coarse.period_px, params, image.shape, full=True)
        for step in (1, 2):
            bins = layout.rows(fold(image, coarse.frame, layout.strips, step=step), layout.phase_rows)
            args = (bins, layout.window_starts, layout.window_lengths, layout.window_strip)
            with kernels("numpy"):
                ref = windows_from_bins(*args)
            with kernels("c"):
                got = windows_from_bins(*args)
            empty += int(np.count_nonzero(ref.n == 0))
            for name in ("n", "level", "s", "u", "moments"):
                assert_allclose(getattr(got, name), getattr(ref, name), rtol=1e-12, atol=1e-12, err_msg=name)
            assert_array_equal(got.strip, ref.strip)
    assert empty > 0  # empty bins seen too (every second pixel): their s is the bin's centre


def test_a_round_of_the_windows_gives_the_same_coefficients(views: list[np.ndarray]) -> None:
    params = RulerParams()
    image = views[1]
    coarse = coarse_ruler(image, params.ruler, min_periods=5)
    layout = plan(coarse.frame, coarse.period_px, params, image.shape, full=False)
    bins = fold(image, coarse.frame, layout.strips)
    w = windows_from_bins(
        layout.rows(bins, layout.phase_rows), layout.window_starts, layout.window_lengths, layout.window_strip
    )
    delta = np.random.default_rng(0).uniform(-0.3, 0.3, len(w.n))
    with kernels("numpy"):
        ref, ref_res = _round(w, w.n, _COSINE, delta, residual=True)
    with kernels("c"):
        got, got_res = _round(w, w.n, _COSINE, delta, residual=True)
    assert ref_res is not None
    assert got_res is not None
    assert_allclose(got, ref, rtol=1e-9, atol=1e-9)
    assert_allclose(got_res, ref_res, rtol=1e-9, atol=1e-9)


def test_the_template_folds_and_fits_the_same_profile(views: list[np.ndarray]) -> None:
    params = RulerParams()
    image = views[1]
    coarse = coarse_ruler(image, params.ruler, min_periods=5)
    layout = plan(coarse.frame, coarse.period_px, params, image.shape, full=False)
    bins = fold(image, coarse.frame, layout.strips)
    w = windows_from_bins(
        layout.rows(bins, layout.phase_rows), layout.window_starts, layout.window_lengths, layout.window_strip
    )
    delta = np.random.default_rng(1).uniform(-0.3, 0.3, len(w.n))
    coef, _ = _round(w, w.n, _COSINE, delta, residual=False)
    weight = w.n * (np.random.default_rng(2).uniform(size=w.n.shape) > 0.05)  # some bins dropped
    with kernels("numpy"):
        ref = _folded(w, weight, coef, delta)
        ref_sums = _cosine_sums(
            ref[1][ref[0] > 0] / ref[0][ref[0] > 0], ref[0][ref[0] > 0], ref[2][ref[0] > 0], 64, 32
        )
        ref_grid = _template(w, weight, coef, delta)
    with kernels("c"):
        got = _folded(w, weight, coef, delta)
        got_sums = _cosine_sums(
            ref[1][ref[0] > 0] / ref[0][ref[0] > 0], ref[0][ref[0] > 0], ref[2][ref[0] > 0], 64, 32
        )
        got_grid = _template(w, weight, coef, delta)
    assert np.count_nonzero(ref[0]) > 500
    for a, b in zip(got, ref, strict=True):
        assert_allclose(a, b, rtol=1e-12, atol=1e-9)
    for a, b in zip(got_sums, ref_sums, strict=True):
        assert_allclose(a, b, rtol=1e-9, atol=1e-9 * float(np.abs(b).max()))
    assert np.ptp(ref_grid) > 0.5  # a profile, not noise
    assert_allclose(got_grid, ref_grid, atol=1e-9)


def test_the_tip_zones_give_the_same_contrasts(views: list[np.ndarray]) -> None:
    params = RulerParams()
    for image in views:
        coarse = coarse_ruler(image, params.ruler, min_periods=5)
        layout = plan(coarse.frame, coarse.period_px, params, image.shape, full=True)
        for zone in layout.tips:
            assert zone is not None
            bins = fold(image, coarse.frame, zone)
            rows = len(zone.table)
            strip = np.repeat(np.arange(rows), zone.table[:, 4].astype(np.int64))
            s = bins[:, 2] / np.maximum(bins[:, 0], 1.0)
            profile = np.cos(2 * np.pi * s)  # the fundamental: the zones' strips see it where the lines are
            with kernels("numpy"):
                ref = contrasts(bins, strip, rows, profile, 0.3)
            with kernels("c"):
                got = contrasts(bins, strip, rows, profile, 0.3)
            assert np.nanmax(np.abs(ref[0])) > 5.0  # the lines seen
            assert np.isnan(ref[0]).sum() < rows
            for a, b in zip(got, ref, strict=True):
                assert_array_equal(np.isnan(a), np.isnan(b))
                assert_allclose(a, b, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("upper", [False, True])
def test_a_tip_zone_s_step_fits_the_same(upper: bool) -> None:
    rng = np.random.default_rng(3)
    t = np.linspace(-2.0, -1.4, 19) if not upper else np.linspace(1.4, 2.0, 19)
    edge, sigma = (-1.63, 0.03) if not upper else (1.61, 0.04)
    sign = 1.0 if upper else -1.0
    m = (40.0 + 3.0 * (t - edge)) * ndtr(sign * (edge - t) / sigma) + rng.normal(0.0, 0.5, len(t))
    with kernels("numpy"):
        ref = fit_tip(t, m, -1.6 if not upper else 1.6, 0.03, inside_below=upper)
    with kernels("c"):
        got = fit_tip(t, m, -1.6 if not upper else 1.6, 0.03, inside_below=upper)
    assert abs(ref[0] - edge) < 0.01  # the step found
    assert_allclose(got, ref, rtol=1e-9, atol=1e-10)


def test_the_frame_s_correction_is_fitted_the_same(views: list[np.ndarray]) -> None:
    params = RulerParams()
    for image in views:
        coarse = coarse_ruler(image, params.ruler, min_periods=5)
        layout = plan(coarse.frame, coarse.period_px, params, image.shape, full=True)
        bins = fold(image, coarse.frame, layout.strips)
        w = windows_from_bins(
            layout.rows(bins, layout.phase_rows),
            layout.window_starts,
            layout.window_lengths,
            layout.window_strip,
        )
        phases = window_phases(w, outlier_sigma=3.0, noise_floor_dn=0.3)
        with kernels("numpy"):
            ref = fit_correction(w, phases, perspective=3e-5)
        with kernels("c"):
            got = fit_correction(w, phases, perspective=3e-5)
        assert np.abs(ref.e[:3]).max() > 1e-6  # the coarse frame corrected
        assert 3 <= ref.used == got.used
        assert_allclose(got.e, ref.e, rtol=1e-9, atol=1e-11)
        assert_allclose(got.covariance, ref.covariance, rtol=1e-9, atol=1e-20)
        assert_allclose(got.residual, ref.residual, rtol=1e-9, atol=1e-11)
        assert got.s_centre == pytest.approx(ref.s_centre, rel=1e-12)
        assert got.scale == pytest.approx(ref.scale, rel=1e-9)


@pytest.mark.parametrize("lens", [False, True])
def test_a_whole_measurement_is_the_same(views: list[np.ndarray], lens: bool) -> None:
    params = WITH_LENS if lens else RulerParams()
    for image in views:
        with kernels("numpy"):
            ref = measure_ruler(image, params)
        with kernels("c"):
            got = measure_ruler(image, params)
        assert abs(got.position_mm - ref.position_mm) * 100 <= TOL_PX
        assert abs(got.offset_mm - ref.offset_mm) * 100 <= TOL_PX * 100
        assert got.code.bits == ref.code.bits
        assert got.extra["rejected_bins"] == ref.extra["rejected_bins"]
