"""Issue 13, the image files: no file can crash a batch, exhaust memory, hang, or get a number it
does not deserve. Each test is a row of the issue's table."""

from __future__ import annotations

import base64
import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from station.batch import FileResult, measure_file
from station.cli import main
from station.compute import LocalBackend
from station.imageio import ImageFileError, read_image
from station.vision import MeasureParams, measure
from tests.hostile import cross, run_station, with_sbit, write_png_bomb
from tests.poison import dies_on_poison


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("good")
    image, _ = cross(321.3, 238.7, 3.0)
    cv2.imwrite(str(d / "good.png"), image)
    return d / "good.png"


def _lines(out: bytes) -> list[dict[str, object]]:
    return [json.loads(line) for line in out.decode("utf-8").splitlines()]


def test_a_40000_px_square_png_is_refused_from_its_header_and_the_batch_goes_on(
    tmp_path: Path, good: Path
) -> None:
    bomb = write_png_bomb(tmp_path / "bomb.png", 40000, 40000)
    assert bomb.stat().st_size < 2_000_000  # 1.5 MB on disk, 1.6 GB decoded
    files = [str(good), str(bomb), str(good), str(good)]
    done = run_station("measure", "--json", "-j", "2", *files)
    lines = _lines(done.stdout)
    assert [d["file"] for d in lines] == files, done.stderr.decode()
    assert [d["ok"] for d in lines] == [True, False, True, True]
    assert lines[1]["code"] == "bad_file"
    assert "40000x40000" in str(lines[1]["error"])
    assert "50 Mpx limit" in str(lines[1]["error"])
    assert done.returncode == 1
    assert b"Traceback" not in done.stderr


def test_a_3_mb_png_of_20000_px_square_rgba16_is_refused_before_decoding(tmp_path: Path) -> None:
    bomb = write_png_bomb(tmp_path / "rgba16.png", 20000, 20000, bit_depth=16, colour_type=6)
    assert bomb.stat().st_size < 4_000_000
    done = run_station("measure", "--json", "-j", "1", str(bomb))
    (line,) = _lines(done.stdout)
    assert line["code"] == "bad_file"
    assert "20000x20000" in str(line["error"])
    assert done.returncode == 1


def test_the_pixel_and_byte_caps_are_configurable(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, good: Path
) -> None:
    from station.imageio import ImageLimits, load_image

    with pytest.raises(ImageFileError, match=r"0\.1 Mpx limit"):
        load_image(good, limits=ImageLimits(max_pixels=100_000))
    with pytest.raises(ImageFileError, match="over the 1000 bytes limit"):
        load_image(good, limits=ImageLimits(max_bytes=1000))
    assert main(["measure", "--json", "-j", "1", "--max-megapixels", "0.1", str(good)]) == 1
    assert "0.1 Mpx limit" in json.loads(capsys.readouterr().out)["error"]


def test_a_fifo_among_the_files_is_refused_without_waiting(tmp_path: Path, good: Path) -> None:
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    files = [str(good), str(fifo), str(good)]
    done = run_station("measure", "--json", "-j", "1", *files)
    lines = _lines(done.stdout)
    assert [d["ok"] for d in lines] == [True, False, True]
    assert "FIFO" in str(lines[1]["error"])
    assert lines[1]["code"] == "bad_file"


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_device_nodes_are_refused_without_reading(device: str) -> None:
    done = run_station("measure", "--json", "-j", "1", device)
    (line,) = _lines(done.stdout)
    assert line == {
        "file": device,
        "ok": False,
        "error": "is a character device, not a regular file: only image files are read",
        "code": "bad_file",
    }


def _jpeg(image: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok
    return bytes(buf.tobytes())


def test_a_truncated_jpeg_with_an_end_marker_appended_is_an_error(tmp_path: Path) -> None:
    image, _ = cross(320.0, 240.0, 2.0)
    data = _jpeg(image)
    whole = tmp_path / "whole.jpg"
    whole.write_bytes(data)
    assert measure_file(whole, MeasureParams()).ok  # the whole file is fine
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(data[: int(len(data) * 0.7)] + b"\xff\xd9")  # 30 % of the frame would be grey
    result = measure_file(cut, MeasureParams())
    assert not result.ok
    assert result.code == "bad_file"
    assert "Corrupt JPEG data" in str(result.error)


def test_a_non_utf8_file_name_is_replaced_and_kept_raw_in_base64(tmp_path: Path, good: Path) -> None:
    raw = os.fsencode(tmp_path) + b"/caf\xe9-\xff.png"
    with open(raw, "wb") as f:
        f.write(good.read_bytes())
    done = run_station("measure", "--json", os.fsdecode(raw), cwd=tmp_path)
    text = done.stdout.decode("utf-8")  # strict: no lone surrogates
    assert "\\ud" not in text
    (line,) = _lines(done.stdout)
    assert line["ok"] is True
    assert str(line["file"]).endswith("caf\ufffd-\ufffd.png")
    assert base64.b64decode(str(line["file_bytes_b64"])) == raw
    plain = FileResult.for_path(good).to_json()
    assert "file_bytes_b64" not in plain  # only for names that are not UTF-8


def test_a_worker_that_dies_gives_its_file_an_error_line_and_the_batch_goes_on(
    tmp_path: Path, good: Path
) -> None:
    poison = tmp_path / "poison.png"
    poison.write_bytes(good.read_bytes())
    files = [good, good, poison, good, good, good, good, good]
    results = list(LocalBackend(2, measure_one=dies_on_poison).measure(files, MeasureParams()))
    assert [r.file for r in results] == [str(f) for f in files]
    assert [r.ok for r in results] == [True, True, False, True, True, True, True, True]
    assert results[2].code == "worker_died"
    assert "died" in str(results[2].error)


def _bits(image: np.ndarray, bits: int) -> np.ndarray:
    """An 8-bit image as a camera delivering ``bits``-bit data in the low bits of 16-bit words."""
    return np.rint(image.astype(np.float64) * ((1 << bits) - 1) / 255.0).astype(np.uint16)


@pytest.mark.parametrize("bits", [10, 12, 14])
@pytest.mark.parametrize("mode", ["precise", "paper"])
def test_16_bit_files_with_10_12_14_bit_data_measure_as_their_8_bit_original(bits: int, mode: str) -> None:
    image, _ = cross(300.4, 251.7, -4.0, preset="hard")
    params = MeasureParams(mode=mode)
    reference = measure(image, params)
    m = measure(_bits(image, bits), params)
    assert m.center_px == reference.center_px  # the same 8-bit grey levels, not 16 or 4 of them
    assert m.diagnostics()["bit_depth"] == bits
    assert reference.diagnostics()["bit_depth"] == 8


def test_bit_depth_comes_from_the_png_sbit_chunk_and_set_bit_depth_overrides_it(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    image, _ = cross(310.0, 230.0, 1.0)
    data = _bits(image, 12) // 2  # dim 12-bit data: its largest value fits in 11 bits
    ok, buf = cv2.imencode(".png", data)
    assert ok
    path = tmp_path / "sbit12.png"
    path.write_bytes(with_sbit(bytes(buf.tobytes()), 12))
    assert main(["measure", "--json", "-j", "1", str(path)]) == 0
    assert json.loads(capsys.readouterr().out)["diagnostics"]["bit_depth"] == 12
    assert main(["measure", "--json", "-j", "1", "--set", "bit_depth=16", str(path)]) == 1
    assert json.loads(capsys.readouterr().out)["code"] == "image_quality"  # 16-bit scaling: blank
    plain = tmp_path / "plain.png"
    cv2.imwrite(str(plain), data)
    assert measure(read_image(plain)).diagnostics()["bit_depth"] == 12  # 2047 < 4096: read as 12


def test_the_front_door_refuses_formats_it_cannot_check(tmp_path: Path) -> None:
    from station.imageio import decode_image, load_image

    image, _ = cross(320.0, 240.0)
    ok, buf = cv2.imencode(".webp", image)
    assert ok
    with pytest.raises(ImageFileError, match="not an image format the station reads"):
        decode_image(bytes(buf.tobytes()))
    with pytest.raises(ImageFileError, match="is a directory"):
        load_image(tmp_path)
    with pytest.raises(ImageFileError, match="no such file"):
        load_image(tmp_path / "missing.png")


def test_the_record_reads_captures_through_the_front_door(tmp_path: Path) -> None:
    import hashlib

    from station.record import RecordError, _images

    fifo = tmp_path / "capture.png"
    os.mkfifo(fifo)
    with pytest.raises(RecordError, match="FIFO"):  # refused at once: opening it would block
        _images.read_checked(fifo, "0" * 64)
    bomb = write_png_bomb(tmp_path / "bomb.png", 40000, 40000)
    sha = hashlib.sha256(bomb.read_bytes()).hexdigest()
    with pytest.raises(RecordError, match="50 Mpx limit"):  # refused from the header, never decoded
        _images.read_checked(bomb, sha)
