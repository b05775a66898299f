"""`station measure`: the CLI contract (other issues and scripts depend on it), bad input included."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from sim.artifact import pose_for_center_px, render
from station.cli import main

KEYS = {"file", "ok", "center_px", "center_mm", "corners_px", "lines", "diagnostics"}


def opencv_drawn_cross(cx: float, cy: float, *, width_px: float, angle_deg: float, seed: int) -> np.ndarray:
    """A cross this project never rendered: drawn with OpenCV at 8x, area-averaged down, blurred, noisy."""
    s = 8
    big = np.full((480 * s, 640 * s), 210, np.uint8)
    c, sn = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    half_len, half_w = 2000.0, width_px / 2.0
    for ux, uy in ((c, sn), (-sn, c)):  # the two grooves: long axis along (ux, uy)
        corners = [
            (cx + ux * a - uy * b, cy + uy * a + ux * b)
            for a, b in ((-half_len, -half_w), (half_len, -half_w), (half_len, half_w), (-half_len, half_w))
        ]
        pts = np.array([[(x + 0.5) * s - 0.5, (y + 0.5) * s - 0.5] for x, y in corners])
        cv2.fillPoly(big, [np.round(pts * 16).astype(np.int32)], 35, lineType=cv2.LINE_AA, shift=4)
    small = cv2.resize(big, (640, 480), interpolation=cv2.INTER_AREA).astype(np.float32)
    small = np.asarray(cv2.GaussianBlur(small, (0, 0), 1.2), dtype=np.float32)
    small += np.random.default_rng(seed).normal(0.0, 1.0, small.shape).astype(np.float32)
    return np.clip(np.rint(small), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def images(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("images")
    out: dict[str, Path] = {}
    img, _ = render(pose_for_center_px(310.4, 250.2, rotation_deg=4.0), rng=np.random.default_rng(0))
    cv2.imwrite(str(d / "good.png"), img)
    out["good"] = d / "good.png"
    drawn = opencv_drawn_cross(301.3, 228.7, width_px=77.0, angle_deg=-6.0, seed=1)
    cv2.imwrite(str(d / "drawn.png"), drawn)
    cv2.imwrite(str(d / "drawn_colour.png"), cv2.cvtColor(drawn, cv2.COLOR_GRAY2BGR))
    cv2.imwrite(str(d / "drawn16.tif"), drawn.astype(np.uint16) * 257)
    cv2.imwrite(str(d / "blank.png"), np.full((480, 640), 90, np.uint8))
    cv2.imwrite(str(d / "saturated.png"), np.full((480, 640), 255, np.uint8))
    cv2.imwrite(str(d / "noise.png"), np.random.default_rng(2).integers(0, 256, (480, 640), dtype=np.uint8))
    cv2.imwrite(str(d / "tiny.png"), img[:30, :30])
    one = np.full((480, 640), 200, np.float32)
    one[200:280] = 40
    cv2.imwrite(str(d / "one_groove.png"), cv2.GaussianBlur(one, (0, 0), 1.0).astype(np.uint8))
    cv2.imwrite(
        str(d / "no_groove.png"),
        cv2.GaussianBlur(np.random.default_rng(3).normal(150, 400, (480, 640)), (0, 0), 8)
        .clip(0, 255)
        .astype(np.uint8),
    )
    rot, _ = render(pose_for_center_px(320, 240, rotation_deg=44.0), rng=np.random.default_rng(4))
    cv2.imwrite(str(d / "rot45.png"), rot)
    data = out["good"].read_bytes()
    (d / "truncated.png").write_bytes(data[: len(data) // 2])
    (d / "empty.png").write_bytes(b"")
    (d / "text.png").write_text("not an image\n")
    for p in d.iterdir():
        out[p.stem] = p
    out["missing"] = d / "missing.png"
    return out


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, list[str], str]:
    code = main(["measure", "-j", "1", *args])
    captured = capsys.readouterr()
    return code, captured.out.splitlines(), captured.err


def test_json_contract_on_a_good_image(capsys: pytest.CaptureFixture[str], images: dict[str, Path]) -> None:
    code, out, err = run(capsys, "--json", str(images["good"]))
    assert code == 0
    assert len(out) == 1
    doc = json.loads(out[0])
    assert set(doc) == KEYS
    assert doc["ok"] is True
    assert doc["file"] == str(images["good"])
    assert len(doc["center_px"]) == 2
    assert len(doc["center_mm"]) == 2
    assert np.array(doc["corners_px"]).shape == (4, 2)
    lines = np.array(doc["lines"])
    assert lines.shape == (4, 3)
    np.testing.assert_allclose(lines[:, 0] ** 2 + lines[:, 1] ** 2, 1.0)
    # corners in the order mapped to (0,0), (w,0), (w,w), (0,w): TL, TR, BR, BL in the image
    tl, tr, br, bl = np.array(doc["corners_px"])
    assert tl[0] < tr[0]
    assert bl[0] < br[0]
    assert tl[1] < bl[1]
    assert tr[1] < br[1]
    # each corner lies on its two lines (top/bottom x left/right)
    for corner, (i, j) in zip((tl, tr, br, bl), ((0, 2), (0, 3), (1, 3), (1, 2)), strict=True):
        for k in (i, j):
            assert abs(lines[k, 0] * corner[0] + lines[k, 1] * corner[1] - lines[k, 2]) < 1e-6
    assert abs(doc["center_px"][0] - 310.4) < 0.01
    assert abs(doc["center_px"][1] - 250.2) < 0.01
    assert doc["diagnostics"]["mode"] == "precise"
    assert "Traceback" not in err


def test_images_this_project_never_rendered(
    capsys: pytest.CaptureFixture[str], images: dict[str, Path]
) -> None:
    files = [str(images[k]) for k in ("drawn", "drawn_colour", "drawn16")]
    for mode in ("precise", "paper"):
        code, out, _ = run(capsys, "--json", "--mode", mode, *files)
        assert code == 0
        docs = [json.loads(line) for line in out]
        assert [d["file"] for d in docs] == files
        for d in docs:
            bound = 0.05 if mode == "precise" else 0.2
            assert abs(d["center_px"][0] - 301.3) < bound, d["center_px"]
            assert abs(d["center_px"][1] - 228.7) < bound, d["center_px"]
            assert abs(d["diagnostics"]["rotation_deg"] + 6.0) < 0.1


BAD = {
    "blank": "image is blank",
    "saturated": "image is saturated",
    "noise": "found 0 of 4 edges",
    "tiny": "at least 64x64",
    "one_groove": "found 2 of 4 edges: the vertical groove was not found",
    "no_groove": "found 0 of 4 edges",
    "rot45": "rotated by 4",
    "truncated": "truncated",
    "empty": "file is empty",
    "text": "not an image",
    "missing": "no such file",
}


@pytest.mark.parametrize("mode", ["precise", "paper"])
def test_every_bad_input_gets_a_specific_error_and_the_cli_goes_on(
    capsys: pytest.CaptureFixture[str], images: dict[str, Path], mode: str
) -> None:
    names = [*BAD, "good"]
    code, out, err = run(capsys, "--json", "--mode", mode, *(str(images[n]) for n in names))
    assert code == 1
    docs = [json.loads(line) for line in out]
    assert [Path(d["file"]).stem for d in docs] == names  # input order, one line each
    for name, doc in zip(names, docs, strict=True):
        if name == "good":
            assert doc["ok"] is True
            continue
        assert doc["ok"] is False
        assert set(doc) == {"file", "ok", "error", "code"}
        assert BAD[name] in doc["error"], (name, doc["error"])
    assert "Traceback" not in err
    assert err.count("station measure:") == len(BAD)


def test_set_is_case_insensitive_and_usage_errors_exit_2(
    capsys: pytest.CaptureFixture[str], images: dict[str, Path]
) -> None:
    code, out, _ = run(
        capsys,
        "--json",
        "--mode",
        "paper",
        "--set",
        "TESTWIDTH=7",
        "--set",
        "filter=gauss",
        str(images["good"]),
    )
    assert code == 0
    params = json.loads(out[0])["diagnostics"]["params"]
    assert (params["testwidth"], params["filter"]) == (7, "gauss")
    for bad in (["--set", "NOPE=1"], ["--set", "skip=0"], ["--set", "filter"], ["--mode", "fast"], []):
        with pytest.raises(SystemExit) as exc:
            main(["measure", *bad, str(images["good"])] if bad else ["measure"])
        assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "unknown parameter" in err
    assert "skip" in err


def test_table_output_without_json_and_parallel_order(
    capsys: pytest.CaptureFixture[str], images: dict[str, Path]
) -> None:
    files = [str(images[k]) for k in ("good", "blank", "drawn", "good", "drawn16")]
    code = main(["measure", "-j", "2", *files])
    out = capsys.readouterr().out
    assert code == 1
    rows = out.splitlines()[2:]
    assert [r.split()[0] for r in rows] == files
    assert "FAILED" in rows[1]
    assert "image is blank" in rows[1]
