"""Each paper-mode stage alone, on inputs whose answer is known by construction."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose

from station.vision import (
    SEED_GAUSS_SIGMA_PX,
    apply_filter,
    apply_threshold,
    directional_responses,
    gauss_kernel_7x7,
    intensity_moment,
    recursive_fit,
    segment_edge,
)
from station.vision import (
    testbox_scan as scan_with_testbox,
)


def step_image(row: int, *, dark_above: bool, shape: tuple[int, int] = (64, 80)) -> np.ndarray:
    img = np.full(shape, 200, np.uint8)
    if dark_above:
        img[:row] = 40
    else:
        img[row:] = 40
    return img


# ---------------------------------------------------------------- stage 1: filters (3.2.1)


def test_gauss_kernel_is_normalised_symmetric_and_halves_per_pixel_at_seed_sigma() -> None:
    k = gauss_kernel_7x7(SEED_GAUSS_SIGMA_PX)
    assert k.shape == (7, 7)
    assert_allclose(k.sum(), 1.0)
    assert_allclose(k, k.T)
    assert_allclose(k, k[::-1, ::-1])
    assert_allclose(k[3, 3] / k[3, 4], 2.0)  # the printed row 2 4 8 16 8 4 2 halves per pixel


def test_filters_leave_input_untouched_and_match_their_definitions() -> None:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (40, 50), dtype=np.uint8)
    before = img.copy()
    assert_allclose(apply_filter(img, "none", gauss_sigma=1.0), img.astype(np.float32))
    mean = apply_filter(img, "mean", gauss_sigma=1.0)
    assert_allclose(mean[10, 10], img[9:12, 9:12].mean(), rtol=1e-5)
    gauss = apply_filter(img, "gauss", gauss_sigma=1.2)
    k = gauss_kernel_7x7(1.2)
    assert_allclose(gauss[20, 20], (img[17:24, 17:24] * k).sum(), rtol=1e-5)
    np.testing.assert_array_equal(img, before)
    with pytest.raises(ValueError, match="filter 'median'"):
        apply_filter(img, "median", gauss_sigma=1.0)


# ---------------------------------------------------------------- stages 2-3: operators, threshold


def test_each_operator_responds_only_to_its_own_polarity() -> None:
    dark_above = step_image(30, dark_above=True).astype(np.float32)
    r = directional_responses(dark_above)
    assert r["bottom"].max() > 0  # eq. 4: dark above, bright below
    assert r["top"].max() == 0
    assert r["left"].max() == 0
    assert r["right"].max() == 0
    # the response sits on the two rows around the step: rows 29 and 30
    assert set(np.nonzero(r["bottom"][:, 40])[0]) == {29, 30}
    r2 = directional_responses(np.ascontiguousarray(dark_above.T))
    assert r2["right"].max() > 0
    assert r2["left"].max() == 0


def test_threshold_zeroes_below_fraction_of_maximum() -> None:
    resp = np.array([[0.0, 10.0, 29.9, 30.0, 100.0]], np.float32)
    out = apply_threshold(resp, 0.30)
    assert_allclose(out, [[0, 0, 0, 30, 100]])
    assert_allclose(resp, [[0.0, 10.0, 29.9, 30.0, 100.0]])
    assert apply_threshold(np.zeros((3, 3), np.float32), 0.3).max() == 0


# ---------------------------------------------------------------- stage 4: TestBox (3.2.4)


def test_testbox_takes_one_pixel_per_column_at_the_column_maximum() -> None:
    resp = np.zeros((40, 30), np.float32)
    resp[10, :] = 5.0
    resp[11, :] = 9.0  # the maximum of column A
    resp[12, :] = 4.0
    pts = scan_with_testbox(resp, testheight=5, testwidth=5, skip=1, backoff=5)
    # columns E and F must exist: the first and last TESTWIDTH columns are never accepted
    assert pts[:, 0].tolist() == list(range(5, 25))
    assert set(pts[:, 1].tolist()) == {11}


def test_testbox_rejects_pixels_near_a_perpendicular_groove() -> None:
    resp = np.zeros((40, 60), np.float32)
    resp[20, :] = 9.0
    resp[20, 28:33] = 0.0  # the edge vanishes across the perpendicular groove
    pts = scan_with_testbox(resp, testheight=3, testwidth=5, skip=1, backoff=3)
    cols = set(pts[:, 0].tolist())
    # a column is accepted only when both E (c-5) and F (c+5) see the edge
    assert not cols & set(range(23, 38))
    assert {22, 38} <= cols


def test_testbox_column_a_maximum_and_skip_and_backoff() -> None:
    resp = np.zeros((50, 40), np.float32)
    resp[10, :] = 3.0  # a weaker line above ...
    resp[13, :] = 8.0  # ... within TESTHEIGHT of a stronger one: rule 2 rejects row 10
    resp[30, :] = 8.0  # a second edge further down, never reached once the first is tracked
    pts = scan_with_testbox(resp, testheight=4, testwidth=2, skip=3, backoff=4)
    assert pts[:, 0].tolist() == list(range(3, 38, 3))
    assert set(pts[:, 1].tolist()) == {13}
    # with TESTHEIGHT 2 the weak line is its own column maximum and comes first scanning down
    pts2 = scan_with_testbox(resp, testheight=2, testwidth=2, skip=1, backoff=2)
    assert set(pts2[:, 1].tolist()) == {10}


def test_segment_edge_maps_all_four_scans_back_to_image_coordinates() -> None:
    img = np.full((60, 70), 200, np.uint8)
    img[20:40, :] = 40  # horizontal groove: top edge between rows 19/20, bottom between 39/40
    img[:, 30:45] = 40  # vertical groove: left edge between cols 29/30, right between 44/45
    r = directional_responses(img.astype(np.float32))
    kw = {"testheight": 3, "testwidth": 5, "skip": 1, "backoff": 3}
    top = segment_edge(apply_threshold(r["top"], 0.3), "top", **kw)
    bottom = segment_edge(apply_threshold(r["bottom"], 0.3), "bottom", **kw)
    left = segment_edge(apply_threshold(r["left"], 0.3), "left", **kw)
    right = segment_edge(apply_threshold(r["right"], 0.3), "right", **kw)
    # scanning down finds row 19 first; scanning up finds row 40 first (ties go to the first reached)
    assert set(top[:, 1].tolist()) == {19}
    assert set(bottom[:, 1].tolist()) == {40}
    assert set(left[:, 0].tolist()) == {29}
    assert set(right[:, 0].tolist()) == {45}
    # near the perpendicular groove (cols 30-44, rows 20-39) pixels are rejected: the operator's
    # response reaches one pixel into the groove, so rejection starts TESTWIDTH - 1 pixels before it
    assert not set(top[:, 0].tolist()) & set(range(26, 49))
    assert not set(left[:, 1].tolist()) & set(range(16, 44))


# ---------------------------------------------------------------- stage 5: moment (eqs. 7-8)


def test_moment_of_uniform_patch_is_the_pixel_and_of_a_step_is_pulled_to_the_bright_side() -> None:
    img = np.full((10, 10), 100, np.uint8)
    refined, valid = intensity_moment(img, np.array([[5, 5], [0, 4]]))
    assert valid.tolist() == [True, False]  # (0, 4) has no full 3x3 neighbourhood
    assert_allclose(refined[0], [5, 5])
    img[:5] = 0  # dark above row 5
    refined, _ = intensity_moment(img, np.array([[5, 5]]))
    # rows 4, 5, 6 weigh 0, 100, 100: y = (5*100 + 6*100) / 200 = 5.5 (the bias the seed keeps)
    assert_allclose(refined[0], [5.0, 5.5])


# ---------------------------------------------------------------- stage 6: recursive fit


def test_recursive_fit_recovers_a_line_and_removes_outliers() -> None:
    rng = np.random.default_rng(1)
    t = np.arange(200, dtype=np.float64)
    s = 0.05 * t + 12.0 + rng.normal(0, 0.05, t.size)
    s[[20, 90, 150]] += [6.0, -8.0, 5.0]
    fit = recursive_fit(t, s, corr_tol=0.0, change_tol=1e-4, max_removals=50)
    assert not fit.kept[[20, 90, 150]].any()
    assert fit.removed >= 3
    assert_allclose(fit.slope, 0.05, atol=5e-4)
    assert_allclose(fit.intercept, 12.0, atol=0.05)
    assert fit.rms_px < 0.08


def test_recursive_fit_reading_corr_tol_on_a_level_line_removes_up_to_the_cap() -> None:
    # Pearson's r of a level line is ~0 however good the fit: a positive corr_tol removes max_removals.
    rng = np.random.default_rng(2)
    t = np.arange(300, dtype=np.float64)
    s = 50.0 + rng.normal(0, 0.1, t.size)
    fit = recursive_fit(t, s, corr_tol=0.5, change_tol=1.0, max_removals=50)
    assert fit.removed == 50
    none = recursive_fit(t, s, corr_tol=0.0, change_tol=1.0, max_removals=50)
    assert none.removed == 0


def test_recursive_fit_rejects_degenerate_input() -> None:
    with pytest.raises(ValueError, match="too few"):
        recursive_fit(np.array([1.0, 2.0]), np.array([1.0, 2.0]), corr_tol=0, change_tol=0, max_removals=1)
    with pytest.raises(ValueError, match="one column"):
        recursive_fit(np.ones(10), np.arange(10.0), corr_tol=0, change_tol=0, max_removals=0)


def test_prewitt_matches_opencv_correlation_definition() -> None:
    rng = np.random.default_rng(3)
    img = rng.normal(100, 20, (30, 30)).astype(np.float32)
    r = directional_responses(img)
    y, x = 15, 12
    expected = img[y + 1, x - 1 : x + 2].sum() - img[y - 1, x - 1 : x + 2].sum()
    assert_allclose(r["bottom"][y, x] - r["top"][y, x], expected, rtol=1e-5)
    assert math.isclose(float(cv2.sumElems(r["top"] * r["bottom"])[0]), 0.0)
