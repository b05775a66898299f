"""The target render's shortcuts (``sim._render_target``) give the frame the plain sum gives.

Three shortcuts: cell lines with no colour change across them take the far pixel's 0 / 1 instead of
``box_step`` (exact by summation by parts); the scene is computed in bands of rows (the gradients from a
row beyond each band); the pixel rays are kept per true camera. Each is held here to the plain
computation: every line exact, the whole frame as one band, the rays computed afresh.
"""

from __future__ import annotations

import numpy as np
import pytest

import sim._render_target as kernels
from sim.lens import true_intrinsics
from sim.target import TargetPose, render_target
from station.camcal import STANDARD_TARGET, ViewSpec

VIEWS = (
    ViewSpec(),  # square, in focus
    ViewSpec(turn_deg=45.0, height_mm=1.5),  # square at 45 deg, defocused
    ViewSpec(tilt_deg=12.0, azimuth_deg=37.0, turn_deg=17.0, height_mm=-0.7, shift_mm=(0.3, -0.2)),
)


def _scene(view: ViewSpec, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    lens = true_intrinsics(seed, tangential_px=0.5)
    pose = TargetPose.from_view(view)
    n = STANDARD_TARGET.cells_per_square()
    assert n is not None
    rays = kernels.pixel_rays(lens, (480, 640))
    face = kernels.target_face(STANDARD_TARGET, n)
    return kernels.scene(rays, pose.rotation, pose.translation_mm, face, STANDARD_TARGET.square_mm / n, 1.0)


def _every_line(
    change: np.ndarray, along: kernels._Axis, across: kernels._Axis, across_lo: int, along_lo: int
) -> np.ndarray:
    return np.ones((along.count - 1, along.coord.size), dtype=bool)


@pytest.mark.parametrize("view", VIEWS, ids=["square", "turned-defocused", "tilted"])
def test_lines_without_a_colour_change_drop_out_exactly(
    view: ViewSpec, monkeypatch: pytest.MonkeyPatch
) -> None:
    evaluated = [0]
    box_step_sorted = kernels.box_step_sorted

    def counted(d: np.ndarray, a: np.ndarray, b: np.ndarray, sigma_px: float) -> np.ndarray:
        evaluated[0] += d.size
        return box_step_sorted(d, a, b, sigma_px)

    monkeypatch.setattr(kernels, "box_step_sorted", counted)
    fast, depth = _scene(view)
    fast_work = evaluated[0]
    monkeypatch.setattr(kernels, "_visible_lines", _every_line)
    plain, plain_depth = _scene(view)
    np.testing.assert_array_equal(depth, plain_depth)
    assert np.abs(fast - plain).max() < 1e-12  # reflectance 0..1: rounding only
    assert 0.2 < plain.mean() < 0.8  # a real frame: black and white
    assert plain.min() < 0.05
    assert plain.max() > 0.95
    assert fast_work < 0.5 * (evaluated[0] - fast_work)  # most lines drop out


def test_the_bands_give_the_whole_frame(monkeypatch: pytest.MonkeyPatch) -> None:
    banded = _scene(VIEWS[2])
    for rows in (2, 7, 480):
        monkeypatch.setattr(kernels, "_BAND_PIXELS", rows * 640)
        other = _scene(VIEWS[2])
        np.testing.assert_array_equal(other[1], banded[1])
        assert np.abs(other[0] - banded[0]).max() < 1e-12


def test_rays_are_kept_per_camera_and_bounded() -> None:
    lenses = [true_intrinsics(seed) for seed in range(1, 7)]
    first = kernels.pixel_rays(lenses[0], (480, 640))
    assert kernels.pixel_rays(lenses[0], (480, 640)) is first  # kept
    assert not first.flags.writeable
    for lens in lenses[1:]:
        rays = kernels.pixel_rays(lens, (480, 640))
        assert not np.array_equal(rays, first)  # keyed on the camera, not shared
    assert len(kernels._rays) <= kernels._RAY_CACHE_SIZE
    again = kernels.pixel_rays(lenses[0], (480, 640))  # evicted, computed afresh: the same rays
    np.testing.assert_array_equal(again, first)
    smaller = kernels.pixel_rays(lenses[0], (240, 320))
    assert smaller.shape == (240, 320, 3)
    np.testing.assert_array_equal(smaller[..., 2], 1.0)


def test_a_frame_does_not_depend_on_the_frames_before() -> None:
    # the caches hold what the frame is computed from, never its result: a frame rendered after others
    # of other cameras and poses is the frame rendered first
    pose = TargetPose.from_view(VIEWS[2])
    lens = true_intrinsics(4)
    first, _ = render_target(pose, intrinsics=lens, defocus_px_per_mm=3.1, rng=np.random.default_rng(9))
    for seed in (1, 2, 5, 6, 7):
        render_target(
            TargetPose.from_view(VIEWS[seed % 2]),
            intrinsics=true_intrinsics(seed),
            defocus_px_per_mm=20.0,
            rng=np.random.default_rng(seed),
        )
    kernels._rays.clear()
    later, _ = render_target(pose, intrinsics=lens, defocus_px_per_mm=3.1, rng=np.random.default_rng(9))
    np.testing.assert_array_equal(later, first)
