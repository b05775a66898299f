"""Following the target's corners into the blur of a square view out of the markers' depth of field,
against the twin's truth (f/4 defocus: 3.1 px/mm; the markers are read within about +/-0.6 mm)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sim.lens import true_intrinsics
from sim.presets import get_preset
from sim.target import F4_DEFOCUS_PX_PER_MM, TargetPose, render_target
from station.camcal import TargetNotFoundError, ViewSpec, detect_target, follow_target
from station.kinds.camera_calibration.views import FOLLOW_SIGMA_PX

TRUTH = true_intrinsics(3)
#: the nominal preset's optics and vignetting without the sensor's noise: the method's own bias
CLEAN = replace(
    get_preset("nominal"), read_noise_dn=0.0, shot_noise_gain_dn_per_e=0.0, salt_pepper_fraction=0.0
)
CENTRE = (319.5, 239.5)


def _frame(view: ViewSpec, preset=CLEAN, seed: int = 0):
    return render_target(
        TargetPose.from_view(view),
        intrinsics=TRUTH,
        preset=preset,
        defocus_px_per_mm=F4_DEFOCUS_PX_PER_MM,
        rng=np.random.default_rng(seed),
    )


@pytest.fixture(scope="module")
def reference():
    image, _ = _frame(ViewSpec(turn_deg=45.0))
    return image, detect_target(image)


@pytest.mark.parametrize("height_mm", [-1.5, 1.5])
def test_corners_are_followed_to_1_5_mm_from_focus_where_the_markers_are_lost(reference, height_mm) -> None:
    image0, found0 = reference
    image, truth = _frame(ViewSpec(turn_deg=45.0, height_mm=height_mm))
    with pytest.raises(TargetNotFoundError):
        detect_target(image)  # the markers cannot be read this far from focus
    scale = 68.0 / (68.0 + height_mm)
    found = follow_target(image, found0, image0, scale=scale, centre_px=CENTRE, sigma_px=FOLLOW_SIGMA_PX)
    assert found.count >= 0.85 * found0.count
    assert set(found.ids) <= set(found0.ids)
    error = found.corners_px - truth.corners_px[found.ids]
    # measured: mean within 0.003 px, 0.033-0.037 px rms (the markers' light at the window's edge)
    assert np.abs(error.mean(axis=0)).max() < 0.005
    assert np.sqrt(np.mean(error**2)) < 0.05


def test_the_arms_sideways_motion_between_heights_is_found(reference) -> None:
    image0, found0 = reference
    # 0.12 mm sideways (12 px), far beyond the refinement's reach: the phase correlation finds it
    image, truth = _frame(ViewSpec(turn_deg=45.0, height_mm=1.0, shift_mm=(0.12, -0.08)))
    found = follow_target(
        image, found0, image0, scale=68.0 / 69.0, centre_px=CENTRE, sigma_px=FOLLOW_SIGMA_PX
    )
    assert found.count >= 0.7 * found0.count
    error = found.corners_px - truth.corners_px[found.ids]
    assert np.sqrt(np.mean(error**2)) < 0.05


def test_a_frame_of_another_size_or_a_wild_scale_is_refused(reference) -> None:
    image0, found0 = reference
    with pytest.raises(TargetNotFoundError, match="take every view with one camera setting"):
        follow_target(image0[:400, :600], found0, image0, scale=1.0, centre_px=CENTRE)
    with pytest.raises(ValueError, match="scale must be"):
        follow_target(image0, found0, image0, scale=3.0, centre_px=CENTRE)
