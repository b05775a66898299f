"""ISO 9283 repeatability on hand-worked examples; validation fits recover known transforms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from station.metrology import compare_displacements, fit_affine, fit_rigid, repeatability


def test_repeatability_hand_worked_square() -> None:
    # four points at distance 1 from their barycentre (0, 0): l_i = 1, l_bar = 1, S_l = 0, RP = 1
    r = repeatability(np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]))
    assert r.barycentre == (0.0, 0.0)
    assert_allclose(r.distances, 1.0)
    assert (r.l_bar, r.s_l, r.rp) == (1.0, 0.0, 1.0)


def test_repeatability_hand_worked_uneven() -> None:
    # points (0,0), (3,0), (0,3), (3,3) + (1.5,1.5): barycentre (1.5, 1.5)
    p = np.array([[0, 0], [3, 0], [0, 3], [3, 3], [1.5, 1.5]], dtype=float)
    r = repeatability(p)
    d = math.hypot(1.5, 1.5)
    assert_allclose(r.distances, [d, d, d, d, 0.0])
    l_bar = 4 * d / 5
    s_l = math.sqrt((4 * (d - l_bar) ** 2 + l_bar**2) / 4)
    assert_allclose([r.l_bar, r.s_l, r.rp], [l_bar, s_l, l_bar + 3 * s_l])


def test_repeatability_hand_worked_in_3d() -> None:
    # the cube's eight corners (+/-1, +/-1, +/-1) and its centre: barycentre 0, eight distances sqrt(3)
    # and one 0; l_bar = 8 sqrt(3) / 9, S_l over N - 1 = 8
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    r = repeatability(np.vstack([corners, [[0.0, 0.0, 0.0]]]))
    d = math.sqrt(3.0)
    assert r.barycentre == (0.0, 0.0, 0.0)
    assert_allclose(r.distances, [d] * 8 + [0.0])
    l_bar = 8 * d / 9
    s_l = math.sqrt((8 * (d - l_bar) ** 2 + l_bar**2) / 8)
    assert_allclose([r.l_bar, r.s_l, r.rp], [l_bar, s_l, l_bar + 3 * s_l])


def test_repeatability_in_3d_with_z_constant_is_the_2d_figure() -> None:
    p2 = np.array([[0, 0], [3, 0], [0, 3], [3, 3], [1.5, 1.5]], dtype=float)
    p3 = np.column_stack([p2, np.full(5, 68.0)])
    assert repeatability(p3).rp == pytest.approx(repeatability(p2).rp)


@pytest.mark.parametrize("shape", [(5, 1), (5, 4), (5,), (1, 3)])
def test_repeatability_refuses_other_shapes(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match=r"\(N, 2\) or \(N, 3\)"):
        repeatability(np.zeros(shape))


def test_repeatability_needs_two_points() -> None:
    with pytest.raises(ValueError, match="N >= 2"):
        repeatability(np.array([[1.0, 2.0]]))


def square_path() -> np.ndarray:
    s = 5.08 * np.arange(10)
    side = 50.8
    return np.concatenate(
        [
            np.column_stack([s, np.zeros(10)]),
            np.column_stack([np.full(10, side), s]),
            np.column_stack([side - s, np.full(10, side)]),
            np.column_stack([np.zeros(10), side - s]),
        ]
    )


def test_rigid_fit_recovers_rotation_and_reports_residuals() -> None:
    c = square_path()
    th = math.radians(1.5)
    R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    m = c @ R.T + [3.0, -2.0]
    fit = fit_rigid(c, m)
    assert_allclose(fit.rotation_deg, 1.5)
    assert fit.max < 1e-9
    noisy = m.copy()
    noisy[7] += [0.5, 0.0]
    assert fit_rigid(c, noisy).max > 0.4


def test_scale_error_shows_in_rigid_and_vanishes_in_similarity_fit() -> None:
    c = square_path()
    m = 0.98 * c  # a groove 2 % narrower than nominal would do this
    comp = compare_displacements(c, m)
    assert comp.rigid.max > 0.3
    assert comp.similarity.max < 1e-9
    assert_allclose(comp.similarity.scale, 0.98)


def test_affine_fit_absorbs_non_perpendicular_table_axes() -> None:
    c = square_path()
    skew = math.radians(0.5)
    A = np.array([[1.0, math.sin(skew)], [0.0, math.cos(skew)]])
    m = c @ A.T
    assert fit_rigid(c, m).max > 0.1
    assert fit_affine(c, m).max < 1e-9
    with pytest.raises(ValueError, match="collinear"):
        fit_affine(c[:10], c[:10])
