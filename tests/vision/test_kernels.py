"""The compiled kernels (``station/vision/_ckernels.c``) against the numpy reference (issue 12).

The numpy code stays the reference: on the benchmark's image sets both give the same results within
1e-9 px (centre, corners, lines), the same points in every fit and the same errors, word for word, in
both modes. Paper mode's results are also pinned, for both, in ``test_paper_reference``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from station.imageio import read_image
from station.vision import EDGES, MeasurementError, MeasureParams, measure
from station.vision._kernels import ENV, available, compiled, kernels, use_kernels
from tests.vision.conftest import Render, paper_reference

TOL_PX = 1e-9


def test_the_install_built_the_compiled_kernels() -> None:
    # `make setup` builds them (gcc and the Python headers are part of the set-up); without them the
    # numpy reference would run and this file would test nothing
    assert available(), "station/vision/_ckernels was not built: run `make setup` (needs gcc)"
    with kernels("c"):
        assert compiled() is not None
    with kernels("numpy"):
        assert compiled() is None


def test_the_choice_is_checked_and_restored() -> None:
    before = compiled()
    with pytest.raises(ValueError, match=ENV):
        use_kernels("fortran")
    with kernels("numpy"):
        assert compiled() is None
    assert compiled() is before


def _both(image: np.ndarray, params: MeasureParams) -> dict[str, object]:
    out: dict[str, object] = {}
    for kernel in ("numpy", "c"):
        with kernels(kernel):
            try:
                out[kernel] = measure(image, params)
            except MeasurementError as exc:
                out[kernel] = f"{exc.code}: {exc}"
    return out


def _assert_same(out: dict[str, object], name: str) -> None:
    ref, got = out["numpy"], out["c"]
    if isinstance(ref, str) or isinstance(got, str):
        assert got == ref, name
        return
    assert_allclose(got.center_px, ref.center_px, rtol=0, atol=TOL_PX, err_msg=name)  # type: ignore[attr-defined]
    assert_allclose(got.corners_px, ref.corners_px, rtol=0, atol=TOL_PX, err_msg=name)  # type: ignore[attr-defined]
    assert_allclose(got.lines, ref.lines, rtol=0, atol=TOL_PX, err_msg=name)  # type: ignore[attr-defined]
    for e in EDGES:
        a, b = got.edges[e], ref.edges[e]  # type: ignore[attr-defined]
        assert (a.segmented, a.used, a.removed) == (b.segmented, b.used, b.removed), f"{name} {e}"
        assert_allclose(a.points, b.points, rtol=0, atol=TOL_PX, err_msg=f"{name} {e}")
        assert a.rms_px == pytest.approx(b.rms_px, rel=1e-9)


@pytest.mark.skipif(not available(), reason="the compiled kernels were not built")
@pytest.mark.parametrize("mode", ["precise", "paper"])
@pytest.mark.parametrize("set_name", list(paper_reference()["sets"]))
def test_kernels_equal_the_numpy_reference_on_the_benchmark(
    bench_sets: Path, set_name: str, mode: str
) -> None:
    params = MeasureParams(mode=mode)
    files = sorted((bench_sets / set_name).glob("*.png"))
    assert files
    for f in files:
        _assert_same(_both(read_image(f), params), f"{set_name}/{f.name}")


@pytest.mark.skipif(not available(), reason="the compiled kernels were not built")
def test_precise_kernels_equal_the_reference_with_every_option(rendered: Render) -> None:
    image, _ = rendered(300.0, 250.0, preset="hard", rotation_deg=7.0, seed=5)
    k = [[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]]
    for params in (
        MeasureParams(flat_field=False),
        MeasureParams(window_px=5, passes=3, profile_step=2),
        MeasureParams(camera_matrix=k, dist_coeffs=[-0.05, 0.01, 0.0, 0.0]),  # float32 samples
    ):
        _assert_same(_both(image, params), str(params))


@pytest.mark.skipif(not available(), reason="the compiled kernels were not built")
def test_precise_kernels_fail_as_the_reference_does(rendered: Render) -> None:
    image, _ = rendered(320.0, 240.0, seed=2)
    cases = {
        # the right land painted as dark as the groove: that edge has no contrast
        "no right edge": np.where(np.arange(640)[None, :] > 360, 40, image).astype(np.uint8),
        # the cross so close to the frame's top that the top edge's profiles leave it
        "at the border": np.ascontiguousarray(image[200:, :]),
        "flat": np.full((480, 640), 128, np.uint8),
    }
    for name, img in cases.items():
        out = _both(img, MeasureParams())
        assert isinstance(out["numpy"], str), name  # each of these is a failure
        _assert_same(out, name)


@pytest.mark.skipif(not available(), reason="the compiled kernels were not built")
@pytest.mark.parametrize("flat_field", [False, True])
def test_the_profiles_kernel_equals_the_reference_and_drops_the_same_windows(flat_field: bool) -> None:
    """Windows leaving the frame are dropped: the same kept profiles, in the same order, the same
    positions, strengths and spreads (with and without the flat field)."""
    from station.vision import _ckernels
    from station.vision._coarse import Illumination
    from station.vision._precise import _profile_points

    rng = np.random.default_rng(1)
    img = (rng.random((120, 160)) * 255).astype(np.uint8)
    along = np.array([5, 50, 100, 150, 5, 60, 110, 10, 60, 100], np.intp)
    owner = np.array([0, 0, 0, 1, 1, 1, 2, 2, 3, 3], np.intp)
    mu = np.array([3.0, 60.5, 116.2, 40.0, -2.0, 80.9, 150.1, 157.9, 20.25, 80.0])
    light = Illumination(np.linspace(1.0, 0.2, 15) * 0.1 + np.r_[1.0, np.zeros(14)] * 0.9, (120, 160))
    illumination = light if flat_field else None
    ref = _profile_points(
        img, along=along, owner=owner, mu=mu, half=4, impulse_dn=25.0, illumination=illumination
    )
    n = along.size
    index, across, strength, spread = np.empty(n, np.int64), np.empty(n), np.empty(n), np.empty(n)
    colcoef, yn = light.pixel_tables() if flat_field else (None, None)
    kept = _ckernels.profiles(
        img, along, owner, mu, 4, 25.0, colcoef, yn, True, index, across, strength, spread
    )
    assert 0 < kept < n  # some windows left the frame
    assert_array_equal(owner[index[:kept]], ref.owner)
    assert_array_equal(along[index[:kept]], ref.along)
    assert_allclose(across[:kept], ref.across, rtol=0, atol=1e-12)
    assert_allclose(strength[:kept], ref.strength, rtol=1e-12)
    assert ref.spread is not None
    assert_allclose(spread[:kept], ref.spread, rtol=1e-9, atol=1e-12)


@pytest.mark.skipif(not available(), reason="the compiled kernels were not built")
@pytest.mark.parametrize("mode", ["precise", "paper"])
def test_the_cross_check_decides_as_the_reference_does(mode: str) -> None:
    """T-junctions, two crosses, crosses near the border: the same verdict and the same sentence."""
    from tests.hostile import cross, t_junction, two_crosses

    images = {
        "T left": t_junction(320.0, 240.0, 5.0, "left", preset="nominal"),
        "T lower": t_junction(300.0, 250.0, -8.0, "lower", preset="hard"),
        "two crosses": two_crosses((200.0, 170.0), (450.0, 330.0)),
        "two on one groove": two_crosses((320.0, 150.0), (320.0, 400.0)),
        "short left arm": cross(58.0, 240.0, 0.0, preset="nominal")[0],
        "two short arms": cross(575.0, 75.0, 12.0, preset="hard")[0],
        "turned": cross(330.0, 250.0, 39.0, preset="hard")[0],
        "specks by the border": cross(338.0, 280.0, 0.0, preset="hard-specks")[0],
        "stub": t_junction(320.0, 240.0, 0.0, "right", preset="hard-specks", ends_px=240.0),
    }
    verdicts = set()
    for name, image in images.items():
        out = _both(image, MeasureParams(mode=mode))
        _assert_same(out, f"{mode} {name}")
        verdicts.add(out["numpy"].split(":")[0] if isinstance(out["numpy"], str) else "measured")
    assert {"incomplete_cross", "measured"} <= verdicts


@pytest.mark.skipif(not available(), reason="the compiled kernels were not built")
def test_the_cross_checks_wall_contrasts_and_arm_ends_are_the_references() -> None:
    """Every wall contrast (NaN where unseen) and every arm's end, exactly, on frames whose arms leave
    the frame straight and aslant, with specks by the border, with a stub and a missing arm."""
    from sim.artifact import pose_for_center_px, truth_for
    from station.vision import EDGES
    from station.vision._geometry import check_cross
    from station.vision._sanity import _Groove, _missing_arms
    from tests.hostile import cross, t_junction

    frames = {
        "specks by the border": (cross(338.0, 280.0, 0.0, preset="hard-specks")[0], (338.0, 280.0, 0.0)),
        "aslant": (cross(150.0, 120.0, 33.0, preset="hard-specks")[0], (150.0, 120.0, 33.0)),
        "T upper": (t_junction(300.0, 250.0, -8.0, "upper", preset="hard"), (300.0, 250.0, -8.0)),
        "stub": (
            t_junction(320.0, 240.0, 0.0, "left", preset="hard-specks", ends_px=200.0),
            (320.0, 240.0, 0.0),
        ),
    }
    for name, (image, (cx, cy, rotation)) in frames.items():
        truth = truth_for(pose_for_center_px(cx, cy, rotation_deg=rotation))
        lines = dict(zip(EDGES, (tuple(line) for line in np.asarray(truth.lines)), strict=True))
        corners = np.asarray(truth.corners_px, dtype=np.float64)
        _, widths = check_cross(lines, corners, image.shape, max_rotation_deg=40.0)
        out = {}
        for kernel in ("numpy", "c"):
            with kernels(kernel):
                small = image[2::4, 2::4].astype(np.float32)
                coarse = image[4::8, 4::8].astype(np.float32)
                grooves = [
                    _Groove(small, coarse, angle, corners.mean(axis=0), width)
                    for angle, width in ((rotation, widths[0]), (rotation + 90.0, widths[1]))
                ]
                out[kernel] = ([g.edges for g in grooves], _missing_arms(grooves[0], grooves[1], widths))
        for ref, got in zip(out["numpy"][0], out["c"][0], strict=True):
            assert np.isnan(ref).any(), name  # the border is in the samples
            assert_array_equal(got, ref, err_msg=name)
        assert out["c"][1] == out["numpy"][1], name
        assert bool(out["numpy"][1]) == (name in ("T upper", "stub")), (name, out["numpy"][1])


@pytest.mark.skipif(not available(), reason="the compiled kernels were not built")
def test_the_quality_check_decides_as_the_reference_does(rendered: Render) -> None:
    from station.vision import check_quality

    image, _ = rendered(320.0, 240.0, seed=4)
    rng = np.random.default_rng(3)
    cases = {
        "cross": image,
        "blank": np.full((480, 640), 77, np.uint8),
        "nearly blank": (77 + rng.integers(0, 9, (480, 640))).astype(np.uint8),
        "saturated": np.where(rng.random((480, 640)) < 0.6, 255, 40).astype(np.uint8),
        "half saturated": np.where(np.arange(640)[None, :] < 320, 255, 30).repeat(480, 0).astype(np.uint8),
        "odd size": (rng.random((67, 93)) * 255).astype(np.uint8),
    }
    for name, img in cases.items():
        verdict = {}
        for kernel in ("numpy", "c"):
            with kernels(kernel):
                try:
                    check_quality(img)
                    verdict[kernel] = "ok"
                except MeasurementError as exc:
                    verdict[kernel] = str(exc)
        assert verdict["c"] == verdict["numpy"], name


@pytest.mark.skipif(not available(), reason="the compiled kernels were not built")
@pytest.mark.parametrize("shape", [(480, 640), (64, 65), (97, 130)])
def test_the_operator_kernels_give_opencvs_values(shape: tuple[int, int]) -> None:
    """Paper mode's operators (whole numbers: exactly equal), extremes and threshold candidates."""
    import cv2

    from station.vision import _ckernels
    from station.vision._edges import operator_responses, threshold_level

    rng = np.random.default_rng(shape[1])
    gray = (rng.random(shape) * 256).astype(np.uint8)
    gray[:, : shape[1] // 3] = 0  # a step: responses of both signs, at the borders too
    gy, gx = np.empty(shape, np.float32), np.empty(shape, np.float32)
    extremes = _ckernels.prewitt(gray, gy, gx)
    ref_y, ref_x = operator_responses(gray)
    assert_array_equal(gy, ref_y)
    assert_array_equal(gx, ref_x)
    (ylo, yhi, _, _), (xlo, xhi, _, _) = cv2.minMaxLoc(ref_y), cv2.minMaxLoc(ref_x)
    assert extremes == (ylo, yhi, xlo, xhi)
    for fraction in (0.0, 0.3, 0.9):
        level = max(threshold_level(yhi, fraction), 0.0)
        got = np.frombuffer(_ckernels.above(gy, level), np.int64)
        assert_array_equal(got, np.flatnonzero(np.abs(ref_y) > level))
