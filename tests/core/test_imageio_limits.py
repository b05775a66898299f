"""The image front door's decoded-size cap (issue 18, row 7): width x height x channels x bytes per
sample, checked from the header before anything is decoded, for every caller; and the core's 8-bit
conversion, which works in bands of rows so that a large 16-bit colour frame needs no float copy of
itself."""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
import pytest

from station.imageio import DEFAULT_MAX_DECODED_BYTES, ImageFileError, ImageLimits, decode_image, read_header
from station.vision import _image


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_header_only(width: int, height: int, bits: int, colour: int) -> bytes:
    """A PNG signature and IHDR, nothing else: only a check of the header can answer about it."""
    ihdr = struct.pack(">IIBBBBB", width, height, bits, colour, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr)


def test_the_decoded_size_is_refused_from_the_header_before_decoding() -> None:
    data = png_header_only(7000, 7000, 16, 2)  # 49 Mpx of 16-bit RGB: under the pixel cap, 280 MiB decoded
    assert read_header(data).decoded_bytes == 7000 * 7000 * 3 * 2
    with pytest.raises(ImageFileError) as caught:
        decode_image(data, name="bomb.png")
    reason = caught.value.reason
    assert "7000x7000 px x 3 channel(s) x 16 bit = 280.4 MiB decoded" in reason
    assert "over the 256.0 MiB limit" in reason
    assert "truncated" not in reason  # the header decided: the data was never looked at


@pytest.mark.parametrize(
    ("bits", "colour", "channels"),
    [(8, 0, 1), (16, 0, 1), (8, 2, 3), (16, 2, 3), (8, 3, 4), (8, 4, 4), (16, 6, 4)],
)
def test_channels_are_counted_as_decoded(bits: int, colour: int, channels: int) -> None:
    """A palette or grey+alpha PNG decodes to BGRA in OpenCV: it counts 4 channels."""
    header = read_header(png_header_only(100, 50, bits, colour))
    assert header.channels == channels
    assert header.decoded_bytes == 100 * 50 * channels * (2 if bits == 16 else 1)


def test_the_cap_is_the_limit_given() -> None:
    image = (np.arange(100 * 120, dtype=np.uint32) * 37 % 65536).astype(np.uint16).reshape(100, 120)
    data = cv2.imencode(".png", image)[1].tobytes()
    exact = 100 * 120 * 2
    assert decode_image(data, limits=ImageLimits(max_decoded_bytes=exact)).image.shape == (100, 120)
    with pytest.raises(ImageFileError, match="decoded, over the"):
        decode_image(data, limits=ImageLimits(max_decoded_bytes=exact - 1))
    assert ImageLimits().max_decoded_bytes == DEFAULT_MAX_DECODED_BYTES == 256 * 2**20
    with pytest.raises(ValueError, match="positive"):
        ImageLimits(max_decoded_bytes=0)


@pytest.mark.parametrize(("channels", "bits"), [(0, 16), (0, 12), (3, 16), (3, 10), (4, 16), (3, 8)])
def test_the_banded_conversion_is_the_whole_frames(channels: int, bits: int) -> None:
    """Bands of rows give exactly what one conversion of the whole frame gives (several bands here)."""
    rng = np.random.default_rng(channels * 100 + bits)
    shape = (1100, 1300, channels) if channels else (1100, 1300)
    dtype = np.uint8 if bits == 8 else np.uint16
    top = (1 << bits) - 1 if bits < 16 else 65535
    image = rng.integers(0, top + 1, size=shape, dtype=np.uint32).astype(dtype)
    if bits not in (8, 16):
        image[0, 0] = min(top + 5, 65535)  # a value above the depth saturates
    assert image[:, :].size > 1 << 20  # more than one band
    arr: npt.NDArray[Any] = image
    if dtype == np.uint16:
        scaled = np.rint(arr.astype(np.float32) * (255.0 / ((1 << bits) - 1)))
        arr = (scaled if bits == 16 else np.minimum(scaled, 255.0)).astype(np.uint8)
    if channels:
        arr = cv2.cvtColor(arr, cv2.COLOR_BGR2GRAY if channels == 3 else cv2.COLOR_BGRA2GRAY)
    got = _image.to_gray8(image, bit_depth=bits if dtype == np.uint16 else None)
    np.testing.assert_array_equal(got, arr)
    assert got.flags.c_contiguous


def test_station_measure_takes_the_cap_as_an_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from station.cli import main

    path = tmp_path / "grey16.png"
    cv2.imwrite(str(path), np.full((200, 300), 1000, np.uint16))  # 120,000 bytes decoded
    assert main(["measure", "--json", "--max-decoded-mb", "0.1", str(path)]) == 1
    line = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert line["ok"] is False
    assert line["code"] == "bad_file"
    assert "120000 bytes decoded, over the 104857 bytes limit" in line["error"]
    with pytest.raises(SystemExit) as usage:
        main(["measure", "--json", "--max-decoded-mb", "0", str(path)])
    assert usage.value.code == 2
