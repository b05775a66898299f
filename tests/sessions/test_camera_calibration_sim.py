"""A camera-calibration session on the simulated station, judged against the twin's true intrinsics.

The twin's camera renders the ChArUco target on the table through intrinsics drawn from a seed (focal
length +/-2 %, principal point +/-20 px, radial distortion: ``sim.lens.true_intrinsics``), the arm moves
through the default 308 views (``plan_views``: 4 square turns, each in focus once and then 26 times at
-1.5 and +1.5 mm, the corners followed into the blur; 96 tilted views), the sensor reads each, and the
fit starts from the nominal camera. Issue 23's targets against the truth: focal lengths within 0.05 %,
principal point within 1 px; the session's own gate: 3 sigma within them.

Measured with the defaults (``TARGET.md``): the focal length's stated uncertainty 0.0126-0.0147 %
(1 sigma), its error against the truth within 0.025 %, the principal point within 0.7 px, on seeds 1 to
7; the gate passes on all but seed 5, whose principal point's 3 sigma is 1.16 px (the session
refuses it and says to take more tilted views). This test runs seed 3 (measured: +0.010 %, sigma
0.0127 %; principal point +0.19 / +0.09 px), once for the module. Fewer views refuse, saying what to
take more of; a looser bound passes and writes the model, the old one kept.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from sim.lens import true_intrinsics
from sim.world import WorldSpec
from station.camera_model import read_camera_model
from station.kinds.camera_calibration.model_file import DEFAULT_NAME, HISTORY_DIR
from station.session import SessionOutcome, run_session

SEED = 3
#: the twin's clock 1000x faster than real; a short settle after each move (the twin's servo decay)
SIM = {"time_scale": 1000.0, "spec": WorldSpec(true_intrinsics_seed=SEED)}
FAST = {"settle_s": 0.005}
#: a small set of views (10) for the refusal and the write path: one pass of two square turns, tilts in
#: four directions
SMALL = {
    **FAST,
    "square_turns_deg": [-45, 45],
    "square_passes": 1,
    "azimuths": 4,
    "tilted_turns_deg": [0],
    "sensor_samples": 3,
}


@pytest.fixture(scope="module")
def default_session(tmp_path_factory: pytest.TempPathFactory) -> tuple[SessionOutcome, Path]:
    data = tmp_path_factory.mktemp("camcal")
    return run_session("camera-calibration", sim=SIM, params=FAST, data=data), data


@pytest.mark.timeout(1200)  # one session of 308 views: 4.5-8 min on a loaded two-core machine
def test_the_default_session_meets_issue_23s_targets_against_the_truth(
    default_session: tuple[SessionOutcome, Path],
) -> None:
    outcome, data = default_session
    r: dict[str, Any] = outcome.results
    truth = true_intrinsics(SEED)
    assert r["views"] == r["views_taken"] == 308  # every view found, the square ones followed into the blur
    assert sum(v["pose_only"] for v in r["view_diagnostics"]) == 4 * 52
    assert r["image_size"] == list(truth.image_size or ())
    assert r["focal_source"] == "heights"  # the scale from the sensor's heights, not the tilted views
    assert r["focal"]["heights"]["range_mm"] > 2.9  # +/-1.5 mm, beyond the markers' +/-0.6 mm
    for name, want in (("fx", truth.fx), ("fy", truth.fy)):
        error = r[name]["value"] / want - 1.0
        assert abs(error) < 5e-4, (name, error)  # issue 23: within 0.05 %
        assert abs(r[name]["value"] - want) < 3.0 * r[name]["sigma"]  # and within its stated uncertainty
        assert 3.0 * r[name]["sigma"] / r[name]["value"] <= 5e-4  # the gate's 3 sigma fits in 0.05 %
    for name, want in (("cx", truth.principal_point[0]), ("cy", truth.principal_point[1])):
        assert abs(r[name]["value"] - want) < 1.0, (name, r[name]["value"] - want)  # within 1 px
        assert abs(r[name]["value"] - want) < 3.0 * r[name]["sigma"]
    assert r["distortion"]["k1"]["sigma"] is not None
    assert r["distortion"]["p1"]["sigma"] is None
    assert r["rms_px"] < 0.1
    # the honest verdict: the gate passed, so the model is written
    assert outcome.state == "succeeded", (outcome.error, r["problems"])
    assert r["problems"] == []
    assert r["camera_model_file"] == str(data / DEFAULT_NAME)
    assert read_camera_model(data / DEFAULT_NAME).fx == pytest.approx(r["fx"]["value"])


@pytest.mark.timeout(240)
def test_too_few_views_refuse_and_say_what_to_take(tmp_path: Path) -> None:
    outcome = run_session("camera-calibration", sim=SIM, params=SMALL, data=tmp_path)
    r = outcome.results
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
