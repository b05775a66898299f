"""Image sets on disk: the validation pattern, files, truth round trip, overwrite policy."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose

from sim.artifact import ArtifactSpec, pose_for_center_px, truth_for
from sim.imageset import (
    ImageSetError,
    ImageSetTruth,
    TableSpec,
    load_displacements,
    load_truth,
    render_random_set,
    render_validation_set,
    validation_pattern_um,
)

STEP = 5.08
TABLE = TableSpec(rotation_deg=2.0, skew_deg=0.5, scale=1.001)
ARTIFACT = ArtifactSpec(groove_width_mm=0.78)
BASE = pose_for_center_px(322.4, 236.1, rotation_deg=-1.5, tilt_x_deg=0.2)


def test_validation_pattern_is_the_seed_square_path() -> None:
    steps = [(1, 0)] * 10 + [(0, 1)] * 10 + [(-1, 0)] * 10 + [(0, -1)] * 9
    expected = np.cumsum([(0, 0), *steps], axis=0) * STEP
    got = np.array(validation_pattern_um())
    assert got.shape == (40, 2)
    assert_allclose(got, expected, atol=1e-12)
    assert got.max() == pytest.approx(50.8)
    assert len({tuple(p) for p in got.round(6)}) == 40  # the start is not repeated
    assert_allclose(np.abs(got[0] - got[-1]).sum(), STEP)  # one step closes the square


def test_table_transform_signs() -> None:
    assert_allclose(TableSpec().matrix(), np.eye(2))
    m = TableSpec(rotation_deg=90.0).matrix()
    assert_allclose(m @ [1.0, 0.0], [0.0, 1.0], atol=1e-15)  # table +x along artifact +v
    skewed = TableSpec(skew_deg=1.0).matrix()
    angle = np.degrees(np.arccos(skewed[:, 0] @ skewed[:, 1]))
    assert angle == pytest.approx(91.0)
    assert_allclose(TableSpec(scale=1.01).matrix(), 1.01 * np.eye(2))
    with pytest.raises(ValueError, match="scale"):
        TableSpec(scale=0.0)


@pytest.fixture(scope="module")
def validation_set(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("sets") / "validation"
    return render_validation_set(
        out, preset="nominal", seed=3, base_pose=BASE, table=TABLE, artifact=ARTIFACT
    )


def test_validation_set_files(validation_set: Path) -> None:
    names = sorted(p.name for p in validation_set.iterdir())
    assert names == sorted([f"img_{k:03d}.png" for k in range(40)] + ["displacements.csv", "truth.json"])
    image = cv2.imread(str(validation_set / "img_017.png"), cv2.IMREAD_UNCHANGED)
    assert image is not None
    assert image.dtype == np.uint8
    assert image.shape == (480, 640)


def test_displacements_csv_is_commanded_um_in_table_axes(validation_set: Path) -> None:
    with (validation_set / "displacements.csv").open(newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["file", "dx_um", "dy_um"]
    assert rows[1] == ["img_000.png", "0.0000", "0.0000"]
    assert rows[11] == ["img_010.png", "50.8000", "0.0000"]
    loaded = load_displacements(validation_set)
    assert [f for f, _, _ in loaded] == [f"img_{k:03d}.png" for k in range(40)]
    assert_allclose([(dx, dy) for _, dx, dy in loaded], validation_pattern_um(), atol=1e-9)


def test_validation_truth_round_trips_and_records_the_true_motion(validation_set: Path) -> None:
    truth = load_truth(validation_set)
    assert isinstance(truth, ImageSetTruth)
    assert (truth.kind, truth.seed, truth.table, truth.artifact) == ("validation", 3, TABLE, ARTIFACT)
    assert truth.preset.name == "nominal"
    assert len(truth.images) == 40
    raw = json.loads((validation_set / "truth.json").read_text())
    assert raw["format"] == "station-imageset/1"
    assert raw["preset"]["read_noise_dn"] == 0.8
    h0 = truth_for(BASE, artifact=ARTIFACT).homography
    for entry, (dx, dy) in zip(truth.images, validation_pattern_um(), strict=True):
        du, dv = entry.artifact_displacement_um or (np.nan, np.nan)
        assert_allclose([du, dv], TABLE.matrix() @ [dx, dy], atol=1e-12)
        expected = truth_for(BASE.displaced(du / 1000, dv / 1000), artifact=ARTIFACT)
        assert_allclose(entry.truth.corners_px, expected.corners_px, atol=1e-12)
        # the crossing moves onto the image of the artifact point it was displaced by
        p = h0 @ [du / 1000, dv / 1000, 1.0]
        assert_allclose(entry.truth.center_px, p[:2] / p[2], atol=1e-9)


def test_sets_are_deterministic_and_refuse_to_overwrite(tmp_path: Path) -> None:
    a = render_random_set(tmp_path / "a", count=3, seed=9)
    b = render_random_set(tmp_path / "b", count=3, seed=9)
    for k in range(3):
        name = f"img_{k:03d}.png"
        assert (a / name).read_bytes() == (b / name).read_bytes()
    assert (a / "truth.json").read_bytes() == (b / "truth.json").read_bytes()
    with pytest.raises(ImageSetError, match="not empty"):
        render_random_set(a, count=2, seed=1)
    (a / "notes.txt").write_text("keep me")
    render_random_set(a, count=2, seed=1, force=True)
    assert sorted(p.name for p in a.iterdir()) == ["img_000.png", "img_001.png", "notes.txt", "truth.json"]
    (tmp_path / "file").write_text("x")
    with pytest.raises(ImageSetError, match="not a folder"):
        render_validation_set(tmp_path / "file")


def test_random_set_stays_inside_the_envelope(tmp_path: Path) -> None:
    out = render_random_set(tmp_path / "r", preset="hard", count=6, seed=4, max_rotation_deg=25.0)
    truth = load_truth(out)
    assert truth.kind == "random"
    assert truth.table is None
    assert truth.preset.name == "hard"
    rotations = []
    for entry in truth.images:
        corners = entry.truth.corners_px
        assert (corners >= 40).all()
        assert (corners[:, 0] <= 599).all()
        assert (corners[:, 1] <= 439).all()
        pose = entry.truth.pose
        assert abs(pose.tilt_x_deg) <= 1.0
        assert abs(pose.tilt_y_deg) <= 1.0
        rotations.append(pose.rotation_deg)
        assert entry.artifact_displacement_um is None
    assert max(np.abs(rotations)) <= 25.0
    assert max(np.abs(rotations)) > 10.0
    with pytest.raises(ImageSetError, match="validation set"):
        load_displacements(out)


def test_loading_rejects_foreign_folders(tmp_path: Path) -> None:
    with pytest.raises(ImageSetError, match="not found"):
        load_truth(tmp_path)
    (tmp_path / "truth.json").write_text(json.dumps({"format": "other/2"}))
    with pytest.raises(ImageSetError, match="other/2"):
        load_truth(tmp_path)
    (tmp_path / "displacements.csv").write_text("file,x,y\n")
    with pytest.raises(ImageSetError, match="header"):
        load_displacements(tmp_path)
