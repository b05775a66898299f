"""Every manual tool takes ``--config`` (issue 23, item 2): ``station camera``, ``station zsensor`` and
``station table`` use the configuration's device and its limits (``station robot``'s are in
tests/drivers/crs_a465)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import tomlkit

from station import config
from station.camera_model import CameraIntrinsics, write_camera_model
from station.cli import main


def write_config(path: Path, **sections: object) -> Path:
    doc = {"name": "lab", "camera": {"driver": "sim"}, **sections}
    path.write_text(tomlkit.dumps(doc), encoding="utf-8")
    return path


def test_camera_grabs_from_the_configured_camera_and_checks_its_models_image_size(tmp_path, capsys):
    wrong = CameraIntrinsics(
        np.array([[6800.0, 0, 400], [0, 6800.0, 300], [0, 0, 1]]), np.zeros(5), (800, 600)
    )
    write_camera_model(wrong, tmp_path / "camera.json")
    good = write_config(tmp_path / "good.toml")
    assert main(["camera", "--config", str(good), "--json", "grab", str(tmp_path / "a.png")]) == 0
    assert json.loads(capsys.readouterr().out)["width"] == 640
    bad = write_config(tmp_path / "bad.toml", camera={"driver": "sim", "camera_model": "camera.json"})
    assert main(["camera", "--config", str(bad), "grab", str(tmp_path / "b.png")]) == 1
    err = capsys.readouterr().err
    assert "holds for 800 x 600 px frames but the camera gives 640 x 480 px" in err
    assert (tmp_path / "b.png").exists()  # nothing captured is lost


def test_zsensor_reads_the_configured_sensor(tmp_path, capsys):
    twin = config.build("distance_sensor_twin", "sim")
    try:
        path = write_config(
            tmp_path / "s.toml",
            distance_sensor={
                "driver": "keyence_il",
                "options": {"port": twin.port, "head": {"model": "IL-065"}},
            },
        )
        assert main(["zsensor", "--config", str(path), "--json", "read"]) == 0
        reading = json.loads(capsys.readouterr().out)
        assert reading["ok"] is True
        assert reading["z_mm"] == pytest.approx(68.0, abs=0.5)  # the twin's camera in focus
    finally:
        twin.close()
    no_sensor = write_config(tmp_path / "n.toml")
    assert main(["zsensor", "--config", str(no_sensor), "read"]) == 2
    assert "no [distance_sensor]" in capsys.readouterr().err


def test_table_refuses_a_target_outside_the_configured_travel_before_asking(tmp_path, capsys):
    small = {
        "driver": "manual",
        "options": {"x_travel_in": [0, 0.5], "y_travel_in": [0, 0.5], "origin_in": [0, 0]},
    }
    path = write_config(tmp_path / "t.toml", table=small)
    assert main(["table", "--sim", "--config", str(path), "move", "20", "0"]) == 1  # 20 mm > 0.5 in
    assert "travel" in capsys.readouterr().err
    assert main(["table", "--sim", "--config", str(path), "--json", "move", "10", "0"]) == 0
    assert json.loads(capsys.readouterr().out)["x_mm"] == pytest.approx(10.0, abs=0.006)
