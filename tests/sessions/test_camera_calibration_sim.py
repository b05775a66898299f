"""A camera-calibration session on the simulated station, judged against the twin's true intrinsics.

The twin's camera renders the ChArUco target on the table through intrinsics drawn from a seed (focal
length +/-2 %, principal point +/-20 px, radial distortion: ``sim.lens.true_intrinsics``), the arm moves
through the default 36 views (``plan_views``), the sensor reads each, and the fit starts from the nominal
camera. Issue 23's targets against the truth: focal lengths within 0.05 %, principal point within 1 px.

At the twin's f/4 depth of field the heights span +/-0.6 mm and the focal length's stated uncertainty is
about 0.1 % (1 sigma; the fitted distances scatter 1.9 um about their lines): 3 sigma does not fit in
0.05 %, so the session fails its gate honestly and writes no model. Measured with the defaults (focal
length error, principal point error cx / cy): seed 3 +0.037 %, 0.12 / 0.40 px (this test); seed 1
-0.015 %, 0.15 / 0.59 px; seed 7 +0.081 %, 0.83 / 0.52 px. The principal point meets 1 px on all three;
the focal length meets 0.05 % on two, and is within its stated uncertainty (1 sigma 0.085-0.105 %) on
all three: the bound the test holds every seed to is 3 sigma, 0.05 % is asserted for seed 3 only. A
looser bound passes and writes the model, the old one kept.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from sim.lens import true_intrinsics
from sim.world import WorldSpec
from station.camera_model import read_camera_model
from station.kinds.camera_calibration.model_file import DEFAULT_NAME, HISTORY_DIR
from station.session import run_session

SEED = 3
#: the twin's clock 1000x faster than real; a short settle after each move (the twin's servo decay)
SIM = {"time_scale": 1000.0, "spec": WorldSpec(true_intrinsics_seed=SEED)}
FAST = {"settle_s": 0.005}
#: a small set of views (14) for the write path: fewer square turns, tilts in four directions
SMALL = {**FAST, "square_turns_deg": [-45, 45], "azimuths": 4, "tilted_turns_deg": [0], "sensor_samples": 3}


@pytest.mark.timeout(240)
def test_the_intrinsics_meet_issue_23s_targets_against_the_truth(tmp_path: Path) -> None:
    outcome = run_session("camera-calibration", sim=SIM, params=FAST, data=tmp_path)
    r = outcome.results
    truth = true_intrinsics(SEED)
    assert r["views"] == r["views_taken"] == 36
    assert r["image_size"] == list(truth.image_size or ())
    assert r["focal_source"] == "heights"  # the scale from the sensor's heights, not the tilted views
    for name, want in (("fx", truth.fx), ("fy", truth.fy)):
        error = r[name]["value"] / want - 1.0
        assert abs(error) < 5e-4, (name, error)  # issue 23: within 0.05 %
        assert abs(r[name]["value"] - want) < 3.0 * r[name]["sigma"]  # and within its stated uncertainty
    for name, want in (("cx", truth.principal_point[0]), ("cy", truth.principal_point[1])):
        assert abs(r[name]["value"] - want) < 1.0, (name, r[name]["value"] - want)  # within 1 px
        assert abs(r[name]["value"] - want) < 3.0 * r[name]["sigma"]
    assert r["distortion"]["k1"]["sigma"] is not None
    assert r["distortion"]["p1"]["sigma"] is None
    assert r["rms_px"] < 0.1
    # the honest verdict: 3 sigma of the focal length does not fit in 0.05 % at f/4, so no model
    assert outcome.state == "failed"
    assert any("fx is known to" in p and "square views" in p for p in r["problems"])
    assert r["camera_model_file"] is None
    assert not (tmp_path / DEFAULT_NAME).exists()


@pytest.mark.timeout(240)
def test_a_passed_calibration_writes_the_model_and_keeps_the_old_one(tmp_path: Path) -> None:
    loose = {**SMALL, "focal_bound_pct": 1.0, "principal_bound_px": 5.0}
    first = run_session("camera-calibration", sim=SIM, params=loose, data=tmp_path)
    assert first.state == "succeeded", first.error
    path = tmp_path / DEFAULT_NAME
    assert first.results["camera_model_file"] == str(path)
    written = read_camera_model(path)
    assert written.image_size == true_intrinsics(SEED).image_size
    assert written.fx == pytest.approx(first.results["fx"]["value"])
    assert written.sigma["fx"] == pytest.approx(first.results["fx"]["sigma"])
    assert written.source["session"] == first.id
    # not configured: the results say to name it in the configuration
    assert any("camera_model" in c["message"] for c in first.results["checks"] if not c["passed"])
    second = run_session("camera-calibration", sim=SIM, params=loose, data=tmp_path)
    assert second.state == "succeeded", second.error
    kept = tmp_path / HISTORY_DIR / "0001.json"
    assert second.results["previous_model_file"] == str(kept)
    assert read_camera_model(kept).source["session"] == first.id
    assert read_camera_model(path).source["session"] == second.id
