"""Issue 13, parameters and options: each bad value exits 2 naming the value and the allowed range;
the camera never grabs a frame it cannot keep; the table checks its inputs before any prompt."""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import pytest

from drivers.xy_table import ManualXYTable
from station.cli import main
from station.devices import MotionRejectedError
from station.prompts import PromptBroker
from tests.hostile import cross
from tests.vision.test_distortion import DIST, K, distort


def max_jobs() -> int:
    """Four worker processes per core: the most --jobs accepts."""
    return 4 * len(os.sched_getaffinity(0))


def usage_error(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    """Run ``station ARGS``, expect exit 2 (argparse's usage error) and return its message."""
    with pytest.raises(SystemExit) as info:
        main(list(args))
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("cli") / "good.png"
    image, _ = cross(320.0, 240.0, 2.0)
    cv2.imwrite(str(path), image)
    return path


@pytest.mark.parametrize("jobs", ["1000", "0", "-5", "two"])
def test_jobs_outside_one_to_four_per_core_is_a_usage_error(
    capsys: pytest.CaptureFixture[str], good: Path, jobs: str
) -> None:
    err = usage_error(capsys, "measure", "-j", jobs, str(good))
    assert "--jobs must be" in err
    assert f"from 1 to {max_jobs()}" in err
    assert jobs in err


def test_jobs_within_range_is_accepted(capsys: pytest.CaptureFixture[str], good: Path) -> None:
    assert main(["measure", "--json", "-j", str(max_jobs()), str(good)]) == 0
    assert json.loads(capsys.readouterr().out)["ok"] is True


@pytest.mark.parametrize(
    ("assignment", "expected"),
    [
        ("threshold=nan", "threshold = 'nan': Input should be a finite number (allowed: 0 < threshold < 1"),
        ("threshold=inf", "threshold = 'inf'"),
        ("impulse_dn=-inf", "impulse_dn = '-inf'"),
        ("groove_width_mm=1e-300", "(allowed: 0.05 <= groove_width_mm <= 50"),
        ("groove_width_mm=51", "groove_width_mm = '51'"),
        ("bit_depth=7", "(allowed: 8 <= bit_depth <= 16, finite (or auto))"),
        ("filter=box", "filter: one of none, mean, gauss"),
    ],
)
def test_bad_parameters_name_the_value_and_the_allowed_range(
    capsys: pytest.CaptureFixture[str], good: Path, assignment: str, expected: str
) -> None:
    err = usage_error(capsys, "measure", "--set", assignment, str(good))
    assert expected in err


def test_bit_depth_auto_and_a_number_are_accepted(capsys: pytest.CaptureFixture[str], good: Path) -> None:
    for value in ("auto", "12"):
        assert main(["measure", "--json", "--set", f"bit_depth={value}", str(good)]) == 0
        assert json.loads(capsys.readouterr().out)["diagnostics"]["bit_depth"] == 8  # an 8-bit file


def test_camera_model_option_is_wired_into_measure(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    image, truth = cross(420.0, 160.0, 3.0)
    warped = tmp_path / "warped.png"
    cv2.imwrite(str(warped), distort(image))
    model = tmp_path / "cam.json"
    model.write_text(json.dumps({"camera_matrix": K.tolist(), "dist_coeffs": DIST.tolist()}))
    assert main(["measure", "--json", "-j", "1", "--camera-model", str(model), str(warped)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert abs(doc["center_px"][0] - truth.center_px[0]) < 0.03
    assert abs(doc["center_px"][1] - truth.center_px[1]) < 0.03
    fifo = tmp_path / "cam-fifo.json"
    os.mkfifo(fifo)
    err = usage_error(capsys, "measure", "--camera-model", str(fifo), str(warped))
    assert "FIFO" in err
    err = usage_error(capsys, "measure", "--camera-model", str(tmp_path / "none.json"), str(warped))
    assert "no such file" in err


def test_camera_output_in_a_missing_directory_is_refused_before_grabbing(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    err = usage_error(capsys, "camera", "--sim", "grab", str(tmp_path / "missing" / "x.png"))
    assert "does not exist: create it first" in err


@pytest.mark.parametrize("name", ["x.jpg", "x.jpeg", "x.bmp", "x"])
def test_camera_output_must_be_lossless(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, name: str
) -> None:
    err = usage_error(capsys, "camera", "--sim", "grab", str(tmp_path / name))
    assert "not a lossless format: name the file .png, .tif or .tiff" in err
    assert not (tmp_path / name).exists()


def test_camera_write_error_is_clear_and_the_frame_is_kept(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    full = tmp_path / "full.png"
    full.symlink_to("/dev/full")  # every write fails with "No space left on device"
    assert main(["camera", "--sim", "grab", str(full)]) == 1
    err = capsys.readouterr().err
    assert "No space left on device" in err
    assert "Traceback" not in err
    kept = Path(err.split("the frame was kept in ")[1].strip())
    image = cv2.imread(str(kept), cv2.IMREAD_UNCHANGED)
    assert image is not None
    assert image.shape == (480, 640)
    kept.unlink()


@pytest.mark.parametrize("n", ["100000", "1001", "0", "-1"])
def test_camera_average_is_one_to_a_thousand(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, n: str
) -> None:
    err = usage_error(capsys, "camera", "--sim", "--average", n, "grab", str(tmp_path / "x.png"))
    assert "--average must be from 1 to 1000" in err


@pytest.mark.parametrize(("x", "y"), [("inf", "0"), ("nan", "0"), ("0", "-inf"), ("1e999", "0")])
def test_table_targets_must_be_finite(capsys: pytest.CaptureFixture[str], x: str, y: str) -> None:
    err = usage_error(capsys, "table", "--sim", "move", "--", x, y)
    assert "must be a finite number" in err
    assert "set X to" not in err  # no prompt was raised


@pytest.mark.parametrize("timeout", ["nan", "inf", "0", "-1"])
def test_table_timeout_is_checked_before_the_prompt(capsys: pytest.CaptureFixture[str], timeout: str) -> None:
    err = usage_error(capsys, "table", "--sim", "--timeout", timeout, "move", "0.1", "0")
    assert "--timeout must be" in err
    assert timeout in err
    assert "set X to" not in err


def test_table_target_out_of_travel_exits_1_without_a_prompt(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["table", "--sim", "move", "30", "0"]) == 1
    err = capsys.readouterr().err
    assert "outside its travel" in err
    assert "set X to" not in err


@pytest.mark.parametrize(
    ("x", "y", "timeout"), [(float("nan"), 0.0, None), (0.0, float("inf"), None), (0.0, 0.0, float("nan"))]
)
def test_the_table_driver_refuses_non_finite_inputs_before_asking(
    x: float, y: float, timeout: float | None
) -> None:
    broker = PromptBroker()
    events: list[object] = []
    broker.subscribe(events.append)
    table = ManualXYTable(broker)
    with pytest.raises(MotionRejectedError, match="finite number"):
        table.move_to(x, y, timeout_s=timeout)
    assert events == []  # nothing was asked
    assert broker.current() is None


@pytest.mark.parametrize("source", ["/dev/zero", "fifo"])
def test_a_scale_calibration_that_is_not_a_regular_file_is_refused(
    capsys: pytest.CaptureFixture[str], good: Path, tmp_path: Path, source: str
) -> None:
    path = source
    if source == "fifo":
        path = str(tmp_path / "cal.json")
        os.mkfifo(path)
    err = usage_error(capsys, "measure", "--scale-calibration", path, str(good))
    assert "not a regular file" in err


def test_a_reader_that_leaves_early_is_no_traceback(tmp_path: Path) -> None:
    """``station sessions | head -0``: the pipe's reader has gone before the station writes; the station
    exits as a shell expects of such a writer (141), with no traceback and no 'Exception ignored'."""
    import subprocess
    import sys

    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        done = subprocess.run(
            [sys.executable, "-m", "station.cli", "sessions", "--data", str(tmp_path / "data")],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
        )
    finally:
        os.close(write_end)
    assert done.returncode == 141, done.stderr
    assert "Traceback" not in done.stderr
    assert "Exception ignored" not in done.stderr
