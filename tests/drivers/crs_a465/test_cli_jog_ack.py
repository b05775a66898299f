"""``station robot --config F jog ...`` and ``acknowledge`` (issue 23, items 1 and 4): jogs checked before
they are sent and run at the jog speed; the stop latch released only at the station's own terminal."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tomlkit

from drivers.crs_a465 import CrsA465
from sim.station import sim_camera_mount, sim_safety
from sim.world import World
from station.cli import main
from station.kinematics import Kinematics

READY = (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)  # where a fresh twin starts


# a fixture 45 mm under the camera's lens front at the ready pose (x 330, y 0, z 439 in the base frame):
# the camera body's capsule (radius 30, its end sphere covered by spheres of 33.5 mm) clears it by 11.5 mm
GAUGE = {
    "shape": "box",
    "name": "height gauge",
    "center_mm": [330.0, 0.0, 374.0],
    "size_mm": [20.0, 20.0, 40.0],
}


def station_toml(tmp_path: Path, **robot_options: str) -> Path:
    world = World()
    safety = sim_safety(world)
    safety["keep_out"] = [*safety["keep_out"], GAUGE]
    doc = {
        "name": "sim-cell",
        "data_dir": str(tmp_path / "data"),
        "robot": {
            "driver": "crs_a465",
            "options": robot_options,
            "reference_joints_deg": list(world.spec.reference_joints_deg),
            "safety": {**safety, "jog_speed_pct": 7},
        },
        "camera": {"driver": "sim", "mount": sim_camera_mount(world).model_dump(exclude_none=True)},
    }
    path = tmp_path / "station.toml"
    path.write_text(tomlkit.dumps(doc), encoding="utf-8")
    return path


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["robot", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_a_camera_jog_moves_the_camera_along_its_own_axis_at_the_jog_speed(capsys, tmp_path):
    config = station_toml(tmp_path)
    code, out, err = run(capsys, "--sim", "--config", str(config), "--json", "jog", "camera", "x", "1.5")
    assert (code, err) == (0, "")
    done = json.loads(out)
    assert (done["kind"], done["axis"], done["unit"], done["speed_pct"]) == ("camera", "x", "mm", 7)
    assert done["start_joints_deg"] == list(READY)
    nominal = Kinematics(tool=sim_camera_mount(World()).matrix())
    before, after = nominal.forward(done["start_joints_deg"]), nominal.forward(done["target_joints_deg"])
    moved = before[:3, :3].T @ (after[:3, 3] - before[:3, 3])  # in the camera's frame
    np.testing.assert_allclose(moved, [1.5, 0.0, 0.0], atol=0.003)  # to the controller's 0.001 deg
    np.testing.assert_allclose(before[:3, :3].T @ after[:3, :3], np.eye(3), atol=3e-5)
    np.testing.assert_allclose(done["commanded_joints_deg"], done["target_joints_deg"], atol=1e-9)


def test_a_camera_jog_without_the_cameras_mounting_is_refused_saying_what_to_add(capsys, tmp_path):
    config = station_toml(tmp_path)
    doc = tomlkit.parse(config.read_text(encoding="utf-8"))
    del doc["camera"]["mount"]
    del doc["robot"]["safety"]["camera_offset_mm"]
    config.write_text(tomlkit.dumps(doc), encoding="utf-8")
    code, out, err = run(capsys, "--sim", "--config", str(config), "jog", "camera", "x", "1.5")
    assert (code, out) == (1, "")  # refused, as a jog the checks refuse
    assert "jogging the camera needs the camera's mounting on the flange: add [camera] mount" in err
    # a joint jog needs no camera frame
    code, out, err = run(capsys, "--sim", "--config", str(config), "--json", "jog", "joint", "1", "0.5")
    assert (code, err) == (0, "")


def test_jogs_are_refused_before_anything_is_sent(capsys, tmp_path):
    config = station_toml(tmp_path)
    code, _, err = run(capsys, "--sim", "--config", str(config), "jog", "camera", "z", "25")
    assert code == 1
    assert "a camera jog is at most 10 mm" in err
    code, _, err = run(capsys, "--sim", "--config", str(config), "jog", "camera", "z", "8")
    assert code == 1  # 8 mm toward the gauge: within the 5 mm clearance (and 1 mm for the sampling)
    assert "camera body would come within" in err
    assert "'height gauge'" in err
    code, _, err = run(capsys, "--sim", "--config", str(config), "jog", "camera", "z", "4")
    assert (code, err) == (0, "")
    code, _, err = run(capsys, "--sim", "jog", "camera", "x", "1")
    assert code == 2
    assert "needs --config" in err


def test_the_stop_latch_outlives_the_call_and_only_the_stations_terminal_releases_it(capsys, tmp_path):
    config = station_toml(tmp_path, port="loop://")
    latch = tmp_path / "data" / "robot-stop-latch.json"
    CrsA465("loop://", latch_file=latch).stop()  # a stop (Ctrl-C of an earlier call, an abort)
    code, _, err = run(capsys, "--sim", "--config", str(config), "jog", "joint", "1", "1")
    assert code == 1
    assert "a stop is latched" in err
    assert "acknowledge" in err
    # from a script (standard input not a terminal): refused, still latched
    script = subprocess.run(
        [sys.executable, "-m", "station.cli", "robot", "--config", str(config), "acknowledge"],
        input="yes\n",
        capture_output=True,
        text=True,
        timeout=60,
        env={k: v for k, v in os.environ.items() if not k.startswith("SSH_")},
    )
    assert script.returncode == 1
    assert "not a terminal" in script.stderr
    assert latch.exists()
    # at a terminal, answering yes: released
    master, slave = os.openpty()
    try:
        person = subprocess.Popen(
            [sys.executable, "-m", "station.cli", "robot", "--config", str(config), "acknowledge"],
            stdin=slave,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={k: v for k, v in os.environ.items() if not k.startswith("SSH_")},
        )
        os.write(master, b"yes\n")
        out, err = person.communicate(timeout=60)
    finally:
        os.close(master)
        os.close(slave)
    assert person.returncode == 0, err
    assert "the stop is latched: stop() from the host" in err
    assert "the stop is acknowledged" in out
    assert not latch.exists()
