"""The ruler's twin renderer (sim/ruler.py): exact truth, exact coverage in the graduation band,
and the hard preset's defects."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import integrate
from scipy.special import ndtr

from sim._render_camera import CameraSpec, Pose, pose_for_center_px
from sim._ruler_surface import get_surface
from sim.presets import get_preset
from sim.ruler import RulerTruth, render_ruler, ruler_coverage, ruler_truth
from station.vision import RulerSpec


def test_truth_under_the_origin_pixel_and_the_principal_point() -> None:
    # the anchor (100 mm on the axis) at pixel (320, 240), the ruler along +x: the origin pixel is
    # 320 px (3.2 mm) back along the ruler and 240 px (2.4 mm) across it, toward -t
    truth = ruler_truth(pose_for_center_px(320, 240), anchor_mm=100.0)
    assert truth.position_mm == pytest.approx(96.8, abs=1e-12)
    assert truth.offset_mm == pytest.approx(-2.4, abs=1e-12)
    assert truth.angle_deg == pytest.approx(0.0, abs=1e-12)
    assert truth.principal_position_mm == pytest.approx(100.0 - 0.005, abs=1e-12)
    assert truth.principal_offset_mm == pytest.approx(-0.005, abs=1e-12)
    turned = ruler_truth(pose_for_center_px(320, 240, rotation_deg=90.0), anchor_mm=100.0)
    # +s now points down the image: the origin pixel is 2.4 mm back along it, 3.2 mm toward +t
    assert turned.position_mm == pytest.approx(97.6, abs=1e-12)
    assert turned.offset_mm == pytest.approx(3.2, abs=1e-12)
    assert turned.angle_deg == pytest.approx(90.0, abs=1e-12)


def test_truth_round_trips_through_json() -> None:
    truth = ruler_truth(pose_for_center_px(300, 250, rotation_deg=33.0, tilt_x_deg=0.4), anchor_mm=12.5)
    again = RulerTruth.from_dict(truth.to_dict())
    assert again.to_dict() == truth.to_dict()
    with pytest.raises(ValueError, match="malformed"):
        RulerTruth.from_dict({"position_mm": 1.0})


def _pixel_average(centre_mm: float, x_px: float, sigma_px: float, px_per_mm: float) -> float:
    """Independent reference: the blurred bar [centre - w/2, centre + w/2] averaged over the pixel."""
    half = 0.125 * px_per_mm

    def value(x: float) -> float:
        c = centre_mm * px_per_mm
        return float(ndtr((x - (c - half)) / sigma_px) - ndtr((x - (c + half)) / sigma_px))

    return float(integrate.quad(value, x_px - 0.5, x_px + 0.5, epsabs=1e-13, epsrel=1e-13)[0])


def test_the_graduation_band_is_the_exact_pixel_average_of_the_blurred_bars() -> None:
    # a ruler along +x, unturned and untilted: along a row inside the lines the coverage is the
    # pixel average of the Gaussian-blurred bars, computed here independently by quadrature
    camera = CameraSpec()
    pose = Pose(x_mm=0.0123, y_mm=0.0)  # graduations at a fraction of a pixel
    coverage = ruler_coverage(pose, anchor_mm=100.0, blur_sigma_px=1.3, camera=camera)
    truth = ruler_truth(pose, anchor_mm=100.0, camera=camera)
    row = 239 - 120  # 1.2 mm toward -t from the axis: inside the lower part of the lines
    s0 = truth.position_mm  # s under pixel (0, 0); s = s0 + x / 100 along the row
    for x in (101, 102, 113, 125, 126, 138, 150):
        s_mm = s0 + x / 100.0
        k = round(s_mm / 0.5)
        expected = sum(_pixel_average((kk * 0.5 - s0), x, 1.3, 100.0) for kk in (k - 1, k, k + 1))
        assert coverage[row, x] == pytest.approx(expected, abs=1e-9), x


def test_a_pixel_centre_exactly_on_an_edge_is_half_covered() -> None:
    # 100 px/mm, the anchor on a pixel centre: bar edges (0.125 mm from graduation centres) fall
    # exactly on pixel centres; each must be half covered, not wholly (a fixed renderer bug)
    pose = pose_for_center_px(320, 240)
    coverage = ruler_coverage(pose, anchor_mm=100.0, blur_sigma_px=1.0)
    row = 240 - 100
    for x in (320 - 12.5, 320 + 12.5):
        if float(x).is_integer():
            assert coverage[row, int(x)] == pytest.approx(0.5, abs=1e-12)
    edges = [320 + 50 * k + d for k in range(-5, 6) for d in (-12.5, 12.5)]
    values = [coverage[row, int(e + 0.5)] + coverage[row, int(e - 0.5)] for e in edges]
    assert np.allclose(values, values[0], atol=1e-12)  # every edge alike


def test_the_code_track_shows_the_code_bits() -> None:
    spec = RulerSpec()
    pose = pose_for_center_px(320, 240)
    coverage = ruler_coverage(pose, anchor_mm=100.0, blur_sigma_px=1.0)
    row = 240 + 20  # t = +0.2 mm: the code track's middle
    bits = spec.code_bits()
    for j in range(800 - 20, 800 + 21):  # cell j at s = j * 0.125 mm; s = 100 mm at x = 320
        x = 320 + round((j * 0.125 - 100.0) * 100)
        assert coverage[row, x] == pytest.approx(float(bits[j]), abs=1e-6), j


def test_the_hard_preset_adds_its_defects_to_the_same_pattern() -> None:
    pose = pose_for_center_px(320, 240, rotation_deg=17.0)
    hard = get_preset("hard")
    quiet = dataclasses.replace(
        hard, read_noise_dn=0.0, shot_noise_gain_dn_per_e=0.0, salt_pepper_fraction=0.0
    )
    clean_surface = dataclasses.replace(
        get_surface("hard"), specks_per_mm2=0.0, scratch_spacing_mm=0.0, gradient=0.0
    )
    plain, truth = render_ruler(
        pose, anchor_mm=60.0, preset=quiet, surface=clean_surface, rng=np.random.default_rng(0)
    )
    worn, truth_worn = render_ruler(pose, anchor_mm=60.0, preset=quiet, rng=np.random.default_rng(0))
    assert truth_worn.to_dict() == truth.to_dict()  # defects change the image, never the truth
    diff = worn.astype(float) - plain.astype(float)
    # illumination: the frame's corners along the light's direction differ by up to 30 % each way
    assert diff[:40, :40].mean() < -10
    assert diff[-40:, -40:].mean() > 10
    # specks and a scratch: small regions far off the smooth light ratio
    ratio = (worn.astype(float) + 1) / (plain.astype(float) + 1)
    smooth = np.abs(ratio - np.median(ratio)) > 0.25
    assert 50 < smooth.sum() < 0.05 * ratio.size
