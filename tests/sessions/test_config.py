"""The station configuration file: what it accepts, what it refuses and how it says so."""

from __future__ import annotations

from pathlib import Path

import pytest

from station.config import ConfigurationError, load_config, open_station, redact

GOOD = """
name = "a465-lab-1"
data_dir = "data"
database = "postgresql://station:s3cret@db.lab/station"

[robot]
driver = "crs_a465"
options = { port = "/dev/ttyS7" }
safety = { max_step_deg = 20, table_z_mm = 0, min_camera_height_mm = 40 }
reference_joints_deg = [0, 30, 60, 0, 90, 0]

[camera]
driver = "v4l2"
options = { device = "/dev/video9" }
camera_model = "camera.json"

[table]
driver = "manual"
options = { origin_in = [0.5, 0.5] }
prompts = "api"

[measure]
mode = "paper"
"""


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "station.toml"
    p.write_text(text, encoding="utf-8")
    return p


def test_a_full_configuration_loads_with_paths_taken_from_its_folder(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path, GOOD))
    assert cfg.name == "a465-lab-1"
    assert cfg.data_dir == tmp_path.resolve() / "data"
    assert cfg.camera.camera_model == tmp_path.resolve() / "camera.json"
    assert cfg.robot is not None
    assert cfg.robot.reference_joints_deg == (0, 30, 60, 0, 90, 0)
    assert cfg.robot.safety["max_step_deg"] == 20
    assert cfg.table is not None
    assert cfg.table.prompts == "api"


def test_the_snapshot_redacts_secrets(tmp_path: Path) -> None:
    snap = load_config(write(tmp_path, GOOD)).snapshot()
    assert "s3cret" not in str(snap)
    assert snap["database"] == "postgresql://station:***@db.lab/station"
    assert redact({"api_token": "abc", "nested": {"password": "x", "port": 1}}) == {
        "api_token": "***",
        "nested": {"password": "***", "port": 1},
    }


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("name = 'x'\n[camera]\ndriver = 'v4l2'\ncolour = 'red'\n", "camera.colour: Extra inputs"),
        (
            "[robot]\ndriver = 'crs_a465'\nreference_joints_deg = [0, 30]\n[camera]\ndriver='v4l2'\n",
            "reference",
        ),
        ("name = 'x'\n", "camera: Field required"),
        ("name = \n", "not valid TOML"),
        (
            "[robot]\ndriver='crs_a465'\nreference_joints_deg=[0,30,60,0,90,nan]\n[camera]\ndriver='v4l2'\n",
            "finite",
        ),
    ],
)
def test_a_bad_configuration_names_the_field(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(ConfigurationError, match=message) as info:
        load_config(write(tmp_path, text))
    assert str(tmp_path) in str(info.value)


def test_a_missing_file_says_so(tmp_path: Path) -> None:
    with pytest.raises(ConfigurationError, match="no such configuration file"):
        load_config(tmp_path / "nope.toml")


def test_devices_are_built_unconnected_and_unknown_drivers_are_named(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path, GOOD))
    devices = open_station(cfg)  # nothing opened: /dev/ttyS7 and /dev/video9 need not exist
    assert devices.robot is not None
    assert devices.table is not None
    assert devices.identities()["camera"]["port"] == "/dev/video9"
    bad = load_config(write(tmp_path, GOOD.replace('driver = "v4l2"', 'driver = "usb3"')))
    with pytest.raises(ConfigurationError, match=r"no camera named 'usb3'; available: .*v4l2"):
        open_station(bad)
    wrong = load_config(
        write(tmp_path, GOOD.replace('options = { device = "/dev/video9" }', "options = { dev = 1 }"))
    )
    with pytest.raises(ConfigurationError, match=r"camera\.v4l2: bad options"):
        open_station(wrong)


def test_a_reanalysis_records_the_scale_calibration_its_source_was_measured_with(tmp_path: Path) -> None:
    """The source's measurement parameters carry its scale calibration's groove width, so the
    re-analysis records the same calibration as its source (unless ``--set groove_width_mm`` replaces
    that width)."""
    from station.record import Record
    from station.session import session_measure_params
    from tests.record.test_sessions import SNAPSHOT

    cal = {"groove_width_mm": 0.2512, "session_id": "a1b2c3d4e5f6", "source": "scale-calibration.json"}
    with Record(tmp_path / "data") as rec:
        src = rec.create_session(
            "repeatability",
            params={"measure": {"groove_width_mm": 0.2512}, "scale_calibration": cal},
            config=SNAPSHOT["config"],
            identities=SNAPSHOT["identities"],
            software=SNAPSHOT["software"],
        )
        params, doc = session_measure_params(rec, "reanalyse", {"session": src.id}, None)
        assert params.groove_width_mm == 0.2512
        assert doc == cal
        params, doc = session_measure_params(
            rec, "reanalyse", {"session": src.id}, None, {"groove_width_mm": 0.25}
        )
        assert params.groove_width_mm == 0.25
        assert doc is None
