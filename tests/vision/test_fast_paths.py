"""The vectorised stages of issue 12 against the straightforward definitions they replace.

Paper mode's sparse TestBox against the dense one (full-image running maxima, ``segment_edge``) and
the column walk against the sequential loop of section 3.2.4; precise mode's grouped statistics
against one edge at a time. Whole-pipeline results are pinned in ``test_paper_reference``.
"""

from __future__ import annotations

from bisect import bisect_left

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from sim.artifact import pose_for_center_px, render
from station.vision import EDGES, Edge, apply_threshold, directional_responses, intensity_moment, segment_edge
from station.vision._coarse import Illumination, fast_median, reduce_4x
from station.vision._edge_fit import _Groups
from station.vision._edges import operator_responses, threshold_level
from station.vision._testbox import scan_columns, segment_edge_sparse


def sequential_walk(accept: np.ndarray, *, skip: int, backoff: int) -> np.ndarray:
    """Section 3.2.4's TestBox walk, one column after another (the reading in ``_testbox``)."""
    w = accept.shape[1]
    out: list[tuple[int, int]] = []
    last: int | None = None
    for j in range(0, w, skip):
        rows = np.flatnonzero(accept[:, j]).tolist()
        start = 0 if last is None else max(0, last - backoff)
        k = bisect_left(rows, start)
        if k == len(rows):
            last = None
            continue
        last = rows[k]
        out.append((j, last))
    return np.array(out, np.intp).reshape(-1, 2)


@pytest.mark.parametrize(
    ("skip", "backoff", "density"), [(1, 5, 0.05), (3, 2, 0.2), (1, 0, 0.5), (2, 9, 0.01)]
)
def test_column_walk_equals_the_sequential_loop(skip: int, backoff: int, density: float) -> None:
    rng = np.random.default_rng(skip * 100 + backoff)
    accept = rng.random((60, 90)) < density
    accept[:, 40:50] = False  # runs of empty columns reset the walk
    ys, xs = np.nonzero(accept)
    got = scan_columns(xs.astype(np.intp), ys.astype(np.intp), accept.shape, skip=skip, backoff=backoff)
    assert_array_equal(got, sequential_walk(accept, skip=skip, backoff=backoff))


def test_column_walk_with_no_accepted_pixels_is_empty() -> None:
    none = np.zeros(0, np.intp)
    assert scan_columns(none, none, (10, 20), skip=1, backoff=3).shape == (0, 2)


def _dense_and_sparse(image: np.ndarray, edge: Edge, **kw: int) -> tuple[np.ndarray, np.ndarray]:
    """``segment_edge`` on the thresholded response and the sparse path on the same image."""
    filtered = image.astype(np.float32)
    dense = segment_edge(apply_threshold(directional_responses(filtered)[edge], 0.3), edge, **kw)
    gy, gx = operator_responses(filtered)
    response = gy if edge in ("top", "bottom") else gx
    sign = -1.0 if edge in ("top", "left") else 1.0
    peak = float((response * sign).max())
    level = max(threshold_level(peak, 0.3), 0.0)
    cand = np.flatnonzero(response * sign > level)
    return dense, segment_edge_sparse(response, sign, edge, level, cand, **kw)


@pytest.mark.parametrize("edge", EDGES)
@pytest.mark.parametrize(
    "kw",
    [
        {"testheight": 5, "testwidth": 5, "skip": 1, "backoff": 5},
        {"testheight": 2, "testwidth": 7, "skip": 3, "backoff": 0},
        {"testheight": 9, "testwidth": 1, "skip": 2, "backoff": 12},
    ],
)
def test_sparse_testbox_equals_the_dense_one_on_noise(edge: Edge, kw: dict[str, int]) -> None:
    # noise puts candidates everywhere, on every border, with ties (whole-number responses)
    rng = np.random.default_rng(5)
    image = rng.integers(0, 256, (70, 90)).astype(np.uint8)
    dense, sparse = _dense_and_sparse(image, edge, **kw)
    assert dense.shape[0] > 10
    assert_array_equal(sparse, dense)


@pytest.mark.parametrize("edge", EDGES)
def test_sparse_testbox_equals_the_dense_one_on_the_artifact(edge: Edge) -> None:
    image, _ = render(
        pose_for_center_px(300.0, 260.0, rotation_deg=12.0), preset="hard", rng=np.random.default_rng(1)
    )
    dense, sparse = _dense_and_sparse(image, edge, testheight=5, testwidth=5, skip=1, backoff=5)
    assert dense.shape[0] > 300
    assert_array_equal(sparse, dense)


def test_moment_by_flat_gather_matches_the_definition() -> None:
    rng = np.random.default_rng(2)
    image = rng.integers(0, 256, (20, 30)).astype(np.uint8)
    points = np.array([[1, 1], [28, 18], [5, 7], [0, 3], [29, 10], [12, 19]], np.intp)
    refined, valid = intensity_moment(image, points)
    assert valid.tolist() == [True, True, True, False, False, False]
    for (x, y), r in zip(points[:3], refined[:3], strict=True):
        patch = image[y - 1 : y + 2, x - 1 : x + 2].astype(np.float64)
        dy, dx = np.mgrid[-1:2, -1:2]
        assert_allclose(
            r, [x + (patch * dx).sum() / patch.sum(), y + (patch * dy).sum() / patch.sum()], atol=1e-12
        )


def test_grouped_medians_equal_one_edge_at_a_time() -> None:
    rng = np.random.default_rng(3)
    owner = np.repeat(np.arange(4), [7, 1, 12, 30])
    values = rng.normal(size=owner.size)
    sel = rng.random(owner.size) < 0.7
    sel[owner == 1] = True
    groups = _Groups(owner)
    counts = groups.count(sel)
    assert counts.tolist() == [int((sel & (owner == i)).sum()) for i in range(4)]
    med = groups.median(values, sel, counts)
    for i in range(4):
        assert med[i] == fast_median(values[sel & (owner == i)])
    # per-edge sums as one product of the selection's weights
    assert_allclose(groups.weights(sel) @ values, [values[sel & (owner == i)].sum() for i in range(4)])


def test_illumination_at_whole_pixels_equals_the_polynomial() -> None:
    rng = np.random.default_rng(4)
    illum = Illumination(rng.normal(0, 0.1, 15) + np.eye(1, 15).ravel(), (48, 64))
    x = rng.integers(0, 64, 50)
    y = rng.integers(0, 48, 50)
    assert_allclose(illum.at_pixels(x, y), illum.at(x.astype(float), y.astype(float)), rtol=1e-12)


@pytest.mark.parametrize("shape", [(480, 640), (203, 161)])
def test_reduce_4x_is_the_mean_of_4x4_blocks_within_a_grey_level(shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(6)
    image = np.asarray(
        cv2.GaussianBlur(rng.integers(0, 256, shape).astype(np.uint8), (0, 0), 2.0), dtype=np.uint8
    )
    small = reduce_4x(image)
    h, w = shape[0] // 4, shape[1] // 4
    blocks = image[: 4 * h, : 4 * w].reshape(h, 4, w, 4).mean(axis=(1, 3))
    assert small.shape == (h, w)
    assert np.abs(small - blocks).max() <= 1.0
