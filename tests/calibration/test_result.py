"""The calibrated parameter set as JSON: round trip, versioning, load_kinematics."""

from __future__ import annotations

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

import station
from sim import calibration_sessions as synthetic
from station.calibration import SCHEMA_VERSION, CalibrationError, CalibrationResult, load_kinematics


def test_json_round_trip_keeps_every_field(fitted, tmp_path):
    path = fitted.result.save(tmp_path / "calibration.json")
    loaded = CalibrationResult.load(path)
    assert loaded == fitted.result
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["schema_version"] == SCHEMA_VERSION
    assert data["software_version"] == station.__version__
    assert data["created"].endswith("+00:00")
    assert {"name", "unit", "nominal", "estimate", "interval", "sigma", "identified"} <= set(
        data["parameters"][0]
    )
    assert len(data["calibrated_dh"]) == 6
    assert "beta_deg" in data["calibrated_dh"][2]
    assert loaded.camera.camera() == synthetic.CAMERA
    assert np.array_equal(np.asarray(loaded.sensor_mount), synthetic.MOUNT)


def test_load_kinematics_gives_the_calibrated_arm_with_the_camera_as_tool(fitted, tmp_path):
    path = fitted.result.save(tmp_path / "calibration.json")
    kin = load_kinematics(path)
    q = np.array([o.joints_deg for o in fitted.observations[:10]])
    assert_allclose(kin.tool_pose(q), fitted.result.kinematics().tool_pose(q), rtol=0, atol=1e-12)
    assert kin.dh[2].beta_deg == fitted.result.calibrated_dh[2].beta_deg != 0.0
    assert_allclose(kin.tool, fitted.result.calibrated_tool)


def test_load_refuses_another_schema_version_saying_what_to_do(fitted, tmp_path):
    data = json.loads(fitted.result.to_json())
    data["schema_version"] = SCHEMA_VERSION + 1
    path = tmp_path / "future.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    with pytest.raises(CalibrationError, match="re-run the identification"):
        load_kinematics(path)


@pytest.mark.parametrize(
    ("content", "message"),
    [("not json", "is not JSON"), ("[1, 2]", "JSON object"), ('{"schema_version": 1}', "not a valid")],
)
def test_load_refuses_a_bad_file(tmp_path, content, message):
    path = tmp_path / "bad.json"
    path.write_text(content, encoding="utf-8")
    with pytest.raises(CalibrationError, match=message):
        CalibrationResult.load(path)


def test_load_names_a_missing_file(tmp_path):
    with pytest.raises(CalibrationError, match="cannot read the calibration file"):
        CalibrationResult.load(tmp_path / "absent.json")
