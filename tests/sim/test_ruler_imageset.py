"""`station sim render-set --artifact ruler`: ruler sets on disk with their truth (issue 22)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from sim._render_camera import CameraSpec
from sim.imageset import TableSpec
from sim.ruler import RulerTruth
from sim.ruler_imageset import (
    FORMAT,
    RulerEnvelope,
    in_view_mm,
    load_ruler_truth,
    random_ruler_views,
    render_ruler_validation_set,
)
from station.cli import main
from station.vision import RulerSpec, measure_ruler


def test_random_set_from_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "set"
    code = main(
        [
            "sim",
            "render-set",
            str(out),
            "--artifact",
            "ruler",
            "--pattern",
            "random",
            "--count",
            "3",
            "--seed",
            "4",
        ]
    )
    assert code == 0
    assert capsys.readouterr().out.strip() == str(out)
    doc = json.loads((out / "truth.json").read_text())
    assert doc["format"] == FORMAT
    assert doc["artifact"] == "ruler"
    assert doc["kind"] == "random"
    assert doc["preset"]["name"] == "nominal"
    assert RulerSpec.model_validate(doc["ruler"]) == RulerSpec()
    assert len(doc["images"]) == 3
    for entry in doc["images"]:
        assert {"file", "position_mm", "offset_mm", "angle_deg"} <= set(entry)
        image = cv2.imread(str(out / entry["file"]), cv2.IMREAD_UNCHANGED)
        assert image is not None
        assert image.shape == (480, 640)
        assert image.dtype == np.uint8
        m = measure_ruler(image)
        assert abs(m.position_mm - entry["position_mm"]) * 100 <= 0.006
    # the same seed draws the same set
    again = tmp_path / "again"
    assert (
        main(
            [
                "sim",
                "render-set",
                str(again),
                "--artifact",
                "ruler",
                "--pattern",
                "random",
                "--count",
                "3",
                "--seed",
                "4",
            ]
        )
        == 0
    )
    for name in ("img_000.png", "img_002.png"):
        assert (out / name).read_bytes() == (again / name).read_bytes()


def test_every_random_view_is_inside_the_envelope() -> None:
    envelope = RulerEnvelope()
    spec, camera = RulerSpec(), CameraSpec()
    for pose, anchor in random_ruler_views(40, seed=2):
        stretch = in_view_mm(pose, anchor, spec, camera, envelope.margin_mm)
        assert stretch is not None
        assert stretch[1] - stretch[0] >= envelope.min_stretch_mm
        assert envelope.margin_mm <= stretch[0] <= stretch[1] <= spec.length_mm - envelope.margin_mm
        assert abs(pose.tilt_x_deg) <= 1.0
        assert abs(pose.tilt_y_deg) <= 1.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--true-width-mm", "0.78"], "--true-width-mm applies to the cross's groove only"),
        (
            ["--pattern", "validation", "--count", "5"],
            "--count and --max-rotation apply to --pattern random only",
        ),
        (["--pattern", "random", "--table-skew-deg", "1"], "apply to --pattern validation only"),
    ],
)
def test_options_that_do_not_apply(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert main(["sim", "render-set", str(tmp_path / "x"), "--artifact", "ruler", *args]) == 1
    assert message in capsys.readouterr().err


def test_an_occupied_folder_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "keep.txt").write_text("mine")
    assert (
        main(
            ["sim", "render-set", str(tmp_path), "--artifact", "ruler", "--pattern", "random", "--count", "1"]
        )
        == 1
    )
    assert "not empty" in capsys.readouterr().err
    assert (tmp_path / "keep.txt").read_text() == "mine"


@pytest.mark.slow
def test_the_validation_series_moves_the_ruler_as_the_table_says(tmp_path: Path) -> None:
    table = TableSpec(rotation_deg=0.5, skew_deg=0.2)
    out = render_ruler_validation_set(tmp_path / "val", seed=3, table=table)
    header, images = load_ruler_truth(out)
    assert header["kind"] == "validation"
    assert len(images) == 40
    with (out / "displacements.csv").open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["file", "dx_um", "dy_um"]
    doc = json.loads((out / "truth.json").read_text())
    first: RulerTruth = images[0][1]
    for (name, truth), row, entry in zip(images, rows[1:], doc["images"], strict=True):
        assert name == row[0]
        ds_um, dt_um = entry["ruler_displacement_um"]
        commanded = np.array([float(row[1]), float(row[2])])
        assert np.allclose([ds_um, dt_um], table.matrix() @ commanded, atol=1e-9)
        # the ruler moved by +ds along itself: the point under the origin pixel by -ds
        assert truth.position_mm - first.position_mm == pytest.approx(-ds_um / 1000.0, abs=2e-6)
