"""Hostile inputs for the robustness tests (issue 13): bombs written by streaming, crafted crosses,
and a runner that puts the station in a subprocess with an address-space limit and a hang guard."""

from __future__ import annotations

import os
import resource
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np

from sim.artifact import pose_for_center_px, render

#: Address space a subprocess may map: the station with its libraries needs well under this; a
#: decompression bomb would need many times more.
ADDRESS_SPACE_BYTES = 3 * 1024**3
#: A run that takes longer has hung (the slowest honest run here takes a few seconds).
HANG_GUARD_S = 30.0

_PNG_CHANNELS = {0: 1, 2: 3, 4: 2, 6: 4}


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def write_png_bomb(path: Path, width: int, height: int, *, bit_depth: int = 8, colour_type: int = 0) -> Path:
    """A valid all-black PNG of ``width`` x ``height`` px, written by streaming compressed chunks.

    The image is never allocated: after a full flush, deflate's output for a block of rows depends
    only on that block, so one compressed block of zero rows is written again and again; the
    stream's Adler-32 for all-zero data is (length mod 65521) << 16 | 1.
    """
    row = 1 + width * _PNG_CHANNELS[colour_type] * bit_depth // 8  # filter byte + samples
    block_rows = max(1, (4 << 20) // row)
    blocks, rest = divmod(height, block_rows)
    ihdr = struct.pack(">IIBBBBB", width, height, bit_depth, colour_type, 0, 0, 0)
    co = zlib.compressobj(9)
    block = bytes(row * block_rows)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr))
        if blocks:
            f.write(_chunk(b"IDAT", co.compress(block) + co.flush(zlib.Z_FULL_FLUSH)))
        if blocks > 1:
            again = _chunk(b"IDAT", co.compress(block) + co.flush(zlib.Z_FULL_FLUSH))
            for _ in range(blocks - 2):
                f.write(again)
            f.write(again)
        tail = co.compress(bytes(row * rest)) + co.flush(zlib.Z_FINISH)
        adler = ((row * height) % 65521) << 16 | 1
        f.write(_chunk(b"IDAT", tail[:-4] + struct.pack(">I", adler)))
        f.write(_chunk(b"IEND", b""))
    return path


def with_sbit(png: bytes, bits: int) -> bytes:
    """A PNG with an sBIT chunk (significant bits per sample) inserted after its header."""
    assert png[12:16] == b"IHDR"
    colour_type = png[25]
    return png[:33] + _chunk(b"sBIT", bytes([bits] * _PNG_CHANNELS[colour_type])) + png[33:]


def cross(
    cx: float, cy: float, rotation_deg: float = 0.0, *, seed: int = 0, preset: str = "nominal"
) -> tuple:
    """A rendered cross (image, truth)."""
    pose = pose_for_center_px(cx, cy, rotation_deg=rotation_deg)
    return render(pose, preset=preset, rng=np.random.default_rng(seed))


def t_junction(
    cx: float,
    cy: float,
    rotation_deg: float,
    missing: str,
    *,
    preset: str = "nominal",
    ends_px: float = 0.0,
) -> np.ndarray:
    """A T-junction: a rendered cross whose ``missing`` arm (left, right, upper, lower) is bare land
    from ``ends_px`` beyond the crossing's corners on (0: the whole arm; more: a stub that long)."""
    image, truth = cross(cx, cy, rotation_deg, preset=preset)
    land, _ = cross(-3000.0, -3000.0, rotation_deg, seed=1, preset=preset)  # the same lands, no groove
    c = np.asarray(truth.corners_px)  # top-left, top-right, bottom-right, bottom-left
    p, q = {"left": (c[3], c[0]), "right": (c[1], c[2]), "upper": (c[0], c[1]), "lower": (c[2], c[3])}[
        missing
    ]
    outward = np.array([q[1] - p[1], -(q[0] - p[0])]) / np.hypot(*(q - p))  # away from the crossing
    p, q = p + ends_px * outward, q + ends_px * outward
    h, w = image.shape
    yy, xx = np.mgrid[0:h, 0:w]
    beyond = (q[0] - p[0]) * (yy - p[1]) - (q[1] - p[1]) * (xx - p[0]) < 0
    return np.where(beyond, land, image)


def two_crosses(first: tuple[float, float], second: tuple[float, float]) -> np.ndarray:
    """Two crosses in one frame (the darker of two renderings, pixel by pixel)."""
    a, _ = cross(*first)
    b, _ = cross(*second, seed=2)
    return np.minimum(a, b)


def _limit_address_space() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE_BYTES, ADDRESS_SPACE_BYTES))


def run_station(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[bytes]:
    """``station ARGS`` in a subprocess with an address-space limit; a hang past 30 s fails the test."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    try:
        return subprocess.run(
            [sys.executable, "-m", "station.cli", *args],
            capture_output=True,
            timeout=HANG_GUARD_S,
            preexec_fn=_limit_address_space,
            env=env,
            cwd=cwd,
            check=False,
        )
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f"station {' '.join(args)} hung for {HANG_GUARD_S:.0f} s") from exc
