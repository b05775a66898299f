"""POST /api/v1/measure: the same object as ``station measure --json``; the image front door's refusals."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from api import _routes_station
from sim.artifact import pose_for_center_px, render
from station.batch import measure_file
from station.vision import MeasureParams
from tests.api.conftest import Served


@pytest.fixture
def png(tmp_path: Path) -> tuple[Path, bytes]:
    img, _ = render(pose_for_center_px(310.4, 250.2, rotation_deg=4.0), rng=np.random.default_rng(0))
    path = tmp_path / "cross.png"
    cv2.imwrite(str(path), img)
    return path, path.read_bytes()


def test_the_result_is_station_measure_json(served: Served, png: tuple[Path, bytes]) -> None:
    path, data = png
    with served.client() as c:
        r = c.post("/api/v1/measure", content=data, headers={"content-type": "image/png"})
        paper = c.post(
            "/api/v1/measure?mode=paper&TESTWIDTH=7", content=data, headers={"content-type": "image/png"}
        )
    assert r.status_code == 200, r.text
    got = r.json()
    want = measure_file(path, MeasureParams()).to_json()
    assert got["ok"] is True
    assert got["center_px"] == want["center_px"]
    assert got["corners_px"] == want["corners_px"]
    assert abs(got["center_px"][0] - 310.4) < 0.05
    want_paper = measure_file(path, MeasureParams(mode="paper", testwidth=7)).to_json()
    assert paper.json()["center_px"] == want_paper["center_px"]


def test_a_failed_measurement_is_200_with_ok_false(served: Served) -> None:
    blank = cv2.imencode(".png", np.full((240, 320), 128, np.uint8))[1].tobytes()
    with served.client() as c:
        r = c.post("/api/v1/measure", content=blank, headers={"content-type": "image/png"})
    assert r.status_code == 200
    assert r.json()["ok"] is False
    assert r.json()["code"] in {"image_quality", "edges_not_found", "invalid_image"}


def test_other_content_types_are_415(served: Served, png: tuple[Path, bytes]) -> None:
    with served.client() as c:
        r = c.post("/api/v1/measure", content=png[1], headers={"content-type": "text/plain"})
    assert r.status_code == 415
    assert "image/png" in r.json()["detail"]


def test_undecodable_images_are_422(served: Served, png: tuple[Path, bytes]) -> None:
    with served.client() as c:
        garbage = c.post(
            "/api/v1/measure", content=b"\x89PNG\r\n\x1a\nnot really", headers={"content-type": "image/png"}
        )
        truncated = c.post("/api/v1/measure", content=png[1][:200], headers={"content-type": "image/png"})
        jpeg = c.post(
            "/api/v1/measure", content=b"\xff\xd8\xff\xe0broken", headers={"content-type": "image/jpeg"}
        )
    for r in (garbage, truncated, jpeg):
        assert r.status_code == 422, r.text
        assert r.json()["code"] == "bad_image"


def test_bad_parameters_are_422(served: Served, png: tuple[Path, bytes]) -> None:
    with served.client() as c:
        unknown = c.post("/api/v1/measure?nonsense=1", content=png[1], headers={"content-type": "image/png"})
        out_of_range = c.post(
            "/api/v1/measure?groove_width_mm=-1", content=png[1], headers={"content-type": "image/png"}
        )
    assert unknown.status_code == 422
    assert "nonsense" in unknown.json()["detail"]
    assert out_of_range.status_code == 422
    assert "groove_width_mm" in out_of_range.json()["detail"]


def test_over_the_size_cap_is_413(
    served: Served, png: tuple[Path, bytes], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(_routes_station, "MAX_UPLOAD_BYTES", 1000)
    with served.client() as c:
        r = c.post("/api/v1/measure", content=png[1], headers={"content-type": "image/png"})
    assert r.status_code == 413
    assert "1000" in r.json()["detail"]


def test_over_the_pixel_cap_is_422(served: Served) -> None:
    # a PNG header declaring 40000 x 40000 px: refused before decoding
    import struct
    import zlib

    ihdr = struct.pack(">IIBBBBB", 40000, 40000, 8, 0, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    data = b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + chunk + struct.pack(">I", zlib.crc32(chunk))
    with served.client() as c:
        r = c.post("/api/v1/measure", content=data, headers={"content-type": "image/png"})
    assert r.status_code == 422
    assert "Mpx" in r.json()["detail"]
