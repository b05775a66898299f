"""Issue 13, the fuzz suite: property-based tests over the image front door, the measurement core's
input, the parameter model and the table and robot argument parsers. None may raise anything but the
project's own error types; nothing may hang or exhaust memory.

Every decode runs in a sandbox subprocess with an address-space limit and a 30 s hang guard: a case
that kills it or hangs fails with that case. Deterministic (``derandomize``), no example database,
no timing assertions; the whole suite runs in well under a minute.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import select
import struct
import subprocess
import sys
import zlib
from collections.abc import Iterator

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from drivers.crs_a465._safety import MotionGuard
from drivers.xy_table import ManualXYTable
from station.cli import build_parser
from station.devices import DeviceError
from station.prompts import PromptBroker
from station.vision import MeasurementError, MeasureParams, measure, parse_assignments
from tests.hostile import ADDRESS_SPACE_BYTES, HANG_GUARD_S, cross

FUZZ = settings(
    max_examples=150,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

# ------------------------------------------------------------------------------------ the sandbox

_SANDBOX = f"""
import json, resource, struct, sys
resource.setrlimit(resource.RLIMIT_AS, ({ADDRESS_SPACE_BYTES}, {ADDRESS_SPACE_BYTES}))
from station.imageio import ImageFileError, decode_image
from station.vision import MeasurementError, measure
inp, out = sys.stdin.buffer, sys.stdout
while True:
    head = inp.read(4)
    if len(head) < 4:
        break
    data = inp.read(struct.unpack(">I", head)[0])
    try:
        image = decode_image(data).image
        reply = {{"decoded": [list(image.shape), str(image.dtype)]}}
        try:
            measure(image)
        except MeasurementError as exc:
            reply["measured"] = exc.code
    except ImageFileError as exc:
        reply = {{"refused": exc.reason}}
    except BaseException as exc:
        reply = {{"raised": type(exc).__name__ + ": " + str(exc)[:300]}}
    out.write(json.dumps(reply) + "\\n")
    out.flush()
"""


class Sandbox:
    """The front door and the core in a subprocess with an address-space limit; one case at a time."""

    def __init__(self) -> None:
        self.cases = 0
        self._start()

    def _start(self) -> None:
        env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
        self.proc = subprocess.Popen(
            [sys.executable, "-c", _SANDBOX], stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env
        )

    def run(self, data: bytes) -> dict[str, object]:
        """The sandbox's reply for one file's bytes; AssertionError if it dies or hangs."""
        assert self.proc.stdin is not None
        assert self.proc.stdout is not None
        self.cases += 1
        try:
            self.proc.stdin.write(struct.pack(">I", len(data)) + data)
            self.proc.stdin.flush()
        except BrokenPipeError:
            pass
        ready, _, _ = select.select([self.proc.stdout], [], [], HANG_GUARD_S)
        line = self.proc.stdout.readline() if ready else b""
        if not line:
            self.close(kill=True)
            self._start()
            what = "hung" if not ready else f"died (exit {self.proc.returncode})"
            raise AssertionError(f"the front door {what} on {len(data)} bytes starting {data[:40]!r}")
        reply: dict[str, object] = json.loads(line)
        assert "raised" not in reply, f"{reply['raised']} on bytes starting {data[:40]!r}"
        return reply

    def close(self, *, kill: bool = False) -> None:
        if kill:
            self.proc.kill()
        for pipe in (self.proc.stdin, self.proc.stdout):
            if pipe is not None:
                with contextlib.suppress(BrokenPipeError):
                    pipe.close()
        self.proc.wait(timeout=HANG_GUARD_S)


@pytest.fixture(scope="module")
def sandbox() -> Iterator[Sandbox]:
    box = Sandbox()
    yield box
    box.close()


# ------------------------------------------------------------------------------------ seed files


def _seed_files() -> dict[str, bytes]:
    image, _ = cross(48.0, 48.0, 5.0)
    small = np.ascontiguousarray(image[192:288, 272:368])  # 96x96 around a crossing
    small = cv2.resize(image, (96, 72), interpolation=cv2.INTER_AREA)
    colour = cv2.cvtColor(small, cv2.COLOR_GRAY2BGR)
    deep = small.astype(np.uint16) * 257
    out = {}
    for name, img, ext in [
        ("png", small, ".png"),
        ("png16", deep, ".png"),
        ("png_colour", colour, ".png"),
        ("jpeg", small, ".jpg"),
        ("jpeg_colour", colour, ".jpg"),
        ("tiff", small, ".tif"),
        ("tiff16", deep, ".tif"),
        ("bmp", small, ".bmp"),
        ("pgm", small, ".pgm"),
        ("ppm", colour, ".ppm"),
    ]:
        ok, buf = cv2.imencode(ext, img)
        assert ok
        out[name] = bytes(buf.tobytes())
    return out


SEEDS = _seed_files()


def test_the_sandbox_decodes_every_seed_file(sandbox: Sandbox) -> None:
    for name, data in SEEDS.items():
        reply = sandbox.run(data)
        assert "decoded" in reply, (name, reply)


# ------------------------------------------------------------------------------------ the front door


@FUZZ
@given(st.binary(max_size=4096))
def test_random_bytes(sandbox: Sandbox, data: bytes) -> None:
    sandbox.run(data)


_SIGNATURES = [b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff", b"II*\x00", b"MM\x00*", b"BM", b"P5\n", b"P6 ", b"P1\n"]


@FUZZ
@given(st.sampled_from(_SIGNATURES), st.binary(max_size=2048))
def test_random_bytes_behind_a_real_signature(sandbox: Sandbox, signature: bytes, tail: bytes) -> None:
    sandbox.run(signature + tail)


@FUZZ
@given(st.sampled_from(sorted(SEEDS)), st.data())
def test_truncated_and_damaged_files(sandbox: Sandbox, name: str, data: st.DataObject) -> None:
    raw = bytearray(SEEDS[name])
    for _ in range(data.draw(st.integers(0, 4), label="flips")):
        at = data.draw(st.integers(0, len(raw) - 1), label="at")
        raw[at] = data.draw(st.integers(0, 255), label="byte")
    cut = data.draw(st.integers(1, len(raw)), label="cut")
    tail = data.draw(st.sampled_from([b"", b"\xff\xd9", b"IEND\xaeB`\x82"]), label="tail")
    sandbox.run(bytes(raw[:cut]) + tail)


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


_DIM = st.one_of(
    st.integers(0, 200), st.integers(0, 2**31 - 1), st.sampled_from([2**16 - 1, 2**31 - 1, 40000])
)


@FUZZ
@given(_DIM, _DIM, st.sampled_from([1, 2, 4, 8, 16, 3, 0, 255]), st.sampled_from([0, 2, 3, 4, 6, 1, 7]))
def test_png_headers_with_any_dimensions(sandbox: Sandbox, w: int, h: int, depth: int, colour: int) -> None:
    ihdr = struct.pack(">IIBBBBB", w, h, depth, colour, 0, 0, 0)
    body = zlib.compress(bytes(4096))
    data = b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", body) + _chunk(b"IEND", b"")
    reply = sandbox.run(data)
    if w * h > 50_000_000:
        assert "refused" in reply  # from the header, before any decoding


@FUZZ
@given(_DIM, _DIM, st.sampled_from([1, 8, 16, 32, 64]), st.sampled_from([1, 2, 3, 4, 5]), st.booleans())
def test_tiff_headers_with_any_dimensions(
    sandbox: Sandbox, w: int, h: int, bits: int, samples: int, big_endian: bool
) -> None:
    o = ">" if big_endian else "<"
    entries = [(256, 4, 1, w), (257, 4, 1, h), (258, 3, 1, bits), (259, 3, 1, 1), (262, 3, 1, 1)]
    entries += [(273, 4, 1, 8 + 2 + 12 * 9 + 4), (277, 3, 1, samples), (278, 4, 1, h), (279, 4, 1, 4096)]
    ifd = struct.pack(o + "H", len(entries))
    for tag, kind, n, value in entries:
        packed = struct.pack(o + "HHI", tag, kind, n)
        ifd += packed + (
            struct.pack(o + "HH", value & 0xFFFF, 0) if kind == 3 else struct.pack(o + "I", value)
        )
    head = (b"MM\x00*" if big_endian else b"II*\x00") + struct.pack(o + "I", 8)
    reply = sandbox.run(head + ifd + b"\x00\x00\x00\x00" + bytes(4096))
    if w * h > 50_000_000:
        assert "refused" in reply  # from the header, before any decoding


@FUZZ
@given(st.integers(-(2**31), 2**31 - 1), st.integers(-(2**31), 2**31 - 1), st.sampled_from([1, 4, 8, 24, 32]))
def test_bmp_headers_with_any_dimensions(sandbox: Sandbox, w: int, h: int, bpp: int) -> None:
    dib = struct.pack("<IiiHHIIiiII", 40, w, h, 1, bpp, 0, 0, 2835, 2835, 0, 0)
    data = b"BM" + struct.pack("<IHHI", 14 + len(dib) + 4096, 0, 0, 14 + len(dib)) + dib + bytes(4096)
    reply = sandbox.run(data)
    if abs(w) * abs(h) > 50_000_000:
        assert "refused" in reply  # from the header, before any decoding


@FUZZ
@given(_DIM, _DIM, st.sampled_from([b"P5", b"P6", b"P2", b"P4"]), st.sampled_from([1, 255, 65535, 70000]))
def test_pnm_headers_with_any_dimensions(sandbox: Sandbox, w: int, h: int, magic: bytes, top: int) -> None:
    reply = sandbox.run(magic + b"\n# comment\n%d %d\n%d\n" % (w, h, top) + bytes(4096))
    if w * h > 50_000_000:
        assert "refused" in reply  # from the header, before any decoding


@FUZZ
@given(st.integers(0, 65535), st.integers(0, 65535))
def test_jpeg_headers_with_any_dimensions(sandbox: Sandbox, w: int, h: int) -> None:
    raw = SEEDS["jpeg"]
    sof = raw.index(b"\xff\xc0")
    data = raw[: sof + 5] + struct.pack(">HH", h, w) + raw[sof + 9 :]
    reply = sandbox.run(data)
    if w * h > 50_000_000:
        assert "refused" in reply  # from the header, before any decoding


# ------------------------------------------------------------------------------------ the core's input

_DTYPES = [np.uint8, np.uint16, np.int8, np.int16, np.int32, np.uint32, np.float32, np.float64, np.bool_]


@FUZZ
@given(
    st.sampled_from(_DTYPES),
    st.sampled_from([(), (1,), (2,), (3,), (4,), (5,)]),
    st.integers(0, 130),
    st.integers(0, 130),
    st.integers(0, 2**32 - 1),
)
def test_measure_accepts_any_array_or_says_why(
    dtype: type, channels: tuple[int, ...], h: int, w: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    info = np.iinfo(dtype) if np.issubdtype(dtype, np.integer) else None
    shape = (h, w, *channels)
    if info is not None:
        image = rng.integers(info.min, info.max, size=shape, dtype=dtype, endpoint=True)
    else:
        image = rng.normal(0, 1e3, size=shape).astype(dtype)
    with contextlib.suppress(MeasurementError):
        measure(image)


@FUZZ
@given(st.sampled_from([0, 1, 3, 4]), st.integers(0, 3))
def test_measure_of_odd_shapes(ndim: int, kind: int) -> None:
    image = np.zeros((70,) * ndim, dtype=[np.uint8, np.uint16, np.float32, np.int64][kind])
    with pytest.raises(MeasurementError):
        measure(image)


# ------------------------------------------------------------------------------------ the parameter model

_FIELDS = sorted(MeasureParams.model_fields)
_VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**6), 10**6),
    st.text(max_size=12),
    st.none(),
    st.booleans(),
    st.sampled_from(["nan", "inf", "-inf", "1e-300", "1e300", "auto", "paper", "gauss", "none"]),
    st.lists(st.floats(allow_nan=True), max_size=4),
)


@FUZZ
@given(st.dictionaries(st.sampled_from(_FIELDS), _VALUES, max_size=5))
def test_the_parameter_model_accepts_or_names_the_value(values: dict[str, object]) -> None:
    try:
        params = MeasureParams.model_validate(values)
    except ValidationError:
        return
    for name in _FIELDS:
        value = getattr(params, name)
        if isinstance(value, float):
            assert math.isfinite(value), (name, value)
    if params.groove_width_mm is not None:
        assert 0.05 <= params.groove_width_mm <= 50


@FUZZ
@given(st.lists(st.text(max_size=20), max_size=4))
def test_set_assignments_parse_or_name_the_assignment(items: list[str]) -> None:
    try:
        parse_assignments(items)
    except ValueError as exc:
        message = str(exc)
    else:
        return
    assert "--set" in message


_PARSER: list[argparse.ArgumentParser] = []


def _parse(args: list[str]) -> argparse.Namespace | None:
    """argparse's verdict: the namespace, or None for a usage error (exit 2)."""
    if not _PARSER:
        _PARSER.append(build_parser())
    try:
        return _PARSER[0].parse_args(args)
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    return None


_NUMBERISH = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["nan", "inf", "-inf", "1e999", "0x10", "", " ", "1_000", "--", "-0"]),
    st.text(max_size=8),
)


@FUZZ
@given(_NUMBERISH, _NUMBERISH, st.one_of(st.none(), _NUMBERISH))
def test_table_arguments_parse_to_finite_numbers_or_exit_2(x: str, y: str, timeout: str | None) -> None:
    extra = [] if timeout is None else [f"--timeout={timeout}"]
    args = _parse(["table", "--sim", *extra, "move", "--", x, y])
    if args is None:
        return
    assert args.timeout is None or (math.isfinite(args.timeout) and args.timeout > 0)
    if isinstance(args.x_mm, float) and isinstance(args.y_mm, float):
        assert math.isfinite(args.x_mm)
        assert math.isfinite(args.y_mm)
    else:  # argparse skips the type check after a second "--" (found by this test): the command refuses
        with pytest.raises(SystemExit) as info:
            args.func(args)
        assert info.value.code == 2


@settings(FUZZ, max_examples=60)
@given(st.floats(allow_nan=True, allow_infinity=True), st.floats(allow_nan=True, allow_infinity=True))
def test_the_table_refuses_or_asks_but_never_crashes(x: float, y: float) -> None:
    table = ManualXYTable(PromptBroker())
    with contextlib.suppress(DeviceError):  # nobody answers: a move in travel is withdrawn at once
        table.move_to(x, y, timeout_s=0.001)


@FUZZ
@given(st.lists(_NUMBERISH, min_size=1, max_size=7), st.sampled_from(["joint", "move-joints", "speed"]))
def test_robot_arguments_parse_or_exit_2(values: list[str], command: str) -> None:
    _parse(["robot", "--sim", command, "--", *values])


@FUZZ
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=6, max_size=6))
def test_the_robot_guard_refuses_or_accepts_any_joints(joints: list[float]) -> None:
    guard = MotionGuard()
    with contextlib.suppress(DeviceError):
        guard.check_limits(joints)
