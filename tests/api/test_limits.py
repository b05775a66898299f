"""What one client may cost the service (issue 18, rows 7 and 14): the decoded-size cap on uploads,
``/measure``'s slots and queue, the header and body timeouts, the connection limit, and a client that
hangs up mid-upload (one log line, no traceback)."""

from __future__ import annotations

import logging
import socket
import struct
import time
import zlib
from collections.abc import Callable

import pytest

from api import ServeLimits
from tests.api.conftest import TOKEN, Served, ServeFactory

FAST = ServeLimits(
    header_timeout_s=0.5, body_idle_s=0.5, body_s=5.0, max_connections=6, measure_slots=1, measure_queue=1
)


@pytest.fixture
def fast(make_served: ServeFactory) -> Served:
    """A service without a station, with short timeouts, 6 connections, one measuring slot and one
    waiting place."""
    return make_served(sim=False, limits=FAST)


def big_png(width: int, height: int) -> bytes:
    """A 16-bit RGB PNG of ``width`` x ``height`` px of one colour, compressed row by row (the test never
    holds the image itself: 7000 x 7000 is 280 MiB decoded, about 1 MB as a file)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    z = zlib.compressobj(9)
    row = b"\x00" + b"\x80\x00" * 3 * width  # filter 0, one mid-grey RGB16 pixel repeated
    idat = b"".join(z.compress(row) for _ in range(height)) + z.flush()
    ihdr = struct.pack(">IIBBBBB", width, height, 16, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def test_an_image_over_the_decoded_size_cap_is_refused_before_decoding(fast: Served) -> None:
    """Row 7: 7000 x 7000 16-bit RGB (49 Mpx, under the pixel cap) took 1.66 GB and 12 s to measure."""
    data = big_png(7000, 7000)
    assert len(data) < 2 * 2**20
    with fast.client() as c:
        r = c.post("/api/v1/measure", content=data, headers={"content-type": "image/png"})
    assert r.status_code == 422, r.text[:300]
    assert r.json()["code"] == "bad_image"
    assert "280.4 MiB decoded, over the 256.0 MiB limit" in r.json()["detail"]


def raw(served: Served) -> socket.socket:
    host, port = served.base.removeprefix("http://").split(":")
    s = socket.create_connection((host, int(port)), timeout=30)
    return s


def upload_head(path: str, ctype: str, length: int) -> bytes:
    return (
        f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nAuthorization: Bearer {TOKEN}\r\n"
        f"Content-Type: {ctype}\r\nContent-Length: {length}\r\n\r\n"
    ).encode()


def answer(s: socket.socket) -> bytes:
    """Everything the server sends until it closes the connection."""
    out = b""
    while chunk := s.recv(65536):
        out += chunk
    return out


def until(condition: Callable[[], object], what: str) -> None:
    """Wait for ``condition()``, ``what`` is waited for (a hang fails through pytest-timeout)."""
    while not condition():
        time.sleep(0.005)


def test_measure_lets_a_few_uploads_in_and_refuses_the_rest(make_served: ServeFactory) -> None:
    fast = make_served(sim=False, limits=ServeLimits(measure_slots=1, measure_queue=1))
    png = big_png(64, 64)
    gate = fast.app.state.measure_gate
    first, second = raw(fast), raw(fast)
    try:
        first.sendall(upload_head("/api/v1/measure", "image/png", len(png)) + png[:10])  # in, reading
        until(lambda: gate.admitted == 1, "the first upload let in")
        second.sendall(upload_head("/api/v1/measure", "image/png", len(png)))  # in: the last place
        until(lambda: gate.admitted == 2, "the second upload let in")
        with fast.client() as c:
            r = c.post("/api/v1/measure", content=png, headers={"content-type": "image/png"})
        assert r.status_code == 503
        assert r.headers["retry-after"] == "1"
        assert r.json()["code"] == "busy"
        first.sendall(png[10:])
        assert b" 200 OK" in answer(first).split(b"\r\n", 1)[0]
        second.sendall(png)
        assert b" 200 OK" in answer(second).split(b"\r\n", 1)[0]
    finally:
        first.close()
        second.close()
    assert (gate.admitted, gate.busy) == (0, 0)


def test_a_header_that_never_completes_is_answered_408_and_closed(fast: Served) -> None:
    """Row 14: slow-header connections were held open indefinitely."""
    s = raw(fast)
    with s:
        s.sendall(b"GET /api/v1/health HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # and no blank line, ever
        reply = answer(s)
    assert reply.startswith(b"HTTP/1.1 408 "), reply[:200]
    assert b'"code": "request_timeout"' in reply


def test_a_kept_alive_connections_next_header_has_the_same_timeout(fast: Served) -> None:
    s = raw(fast)
    with s:
        s.sendall(b"GET /api/v1/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        first = s.recv(65536)
        assert first.startswith(b"HTTP/1.1 200 ")
        s.sendall(b"GET /api/v1/health HTTP/1.1\r\n")
        reply = answer(s)
    assert reply.startswith(b"HTTP/1.1 408 "), reply[:200]


@pytest.mark.parametrize("path", ["/api/v1/sessions", "/api/v1/measure", "/api/v1/sessions/import"])
def test_a_body_that_stalls_is_answered_408_and_closed(fast: Served, path: str) -> None:
    """Row 14: slow-body connections were held open indefinitely."""
    ctype = {"/api/v1/measure": "image/png", "/api/v1/sessions/import": "application/zip"}.get(
        path, "application/json"
    )
    s = raw(fast)
    with s:
        s.sendall(upload_head(path, ctype, 1000) + b"{")
        reply = answer(s)
    assert reply.startswith(b"HTTP/1.1 408 "), reply[:200]
    assert b"request_timeout" in reply
    assert reply.count(b"HTTP/1.1") == 1  # the route's own answer to the lost body is not sent too


def test_connections_over_the_limit_are_refused_at_once(fast: Served) -> None:
    """Row 14: no limit on connections. Idle ones count (they hold a socket and a protocol each)."""
    held = [raw(fast) for _ in range(FAST.max_connections)]
    try:
        extra = raw(fast)
        with extra:
            reply = answer(extra)
        assert reply.startswith(b"HTTP/1.1 503 "), reply[:200]
        assert b"retry-after: 1" in reply.lower()
        assert b"too_many_connections" in reply
    finally:
        for s in held:
            s.close()
    with fast.client() as c:  # the server took the refusal in its stride
        assert c.get("/api/v1/health").status_code == 200


@pytest.fixture
def server_log(caplog: pytest.LogCaptureFixture) -> pytest.LogCaptureFixture:
    caplog.set_level(logging.DEBUG)
    return caplog


@pytest.mark.timeout(30)
@pytest.mark.parametrize("path", ["/api/v1/measure", "/api/v1/sessions/import", "/api/v1/sessions"])
def test_a_client_that_hangs_up_mid_upload_is_one_log_line(
    fast: Served, server_log: pytest.LogCaptureFixture, path: str
) -> None:
    """Row 14: each client that left during an upload logged two tracebacks."""
    ctype = {"/api/v1/measure": "image/png", "/api/v1/sessions/import": "application/zip"}.get(
        path, "application/json"
    )
    server_log.clear()
    s = raw(fast)
    s.sendall(upload_head(path, ctype, 100_000) + b"x" * 1000)
    s.close()
    until(lambda: any(path in r.getMessage() for r in server_log.records), "a log line of the request")
    tasks = fast.server.server_state.tasks
    until(lambda: not tasks, "the request's task ended")  # everything it logs is logged by then
    mine = [r for r in server_log.records if not r.name.startswith(("httpx", "httpcore"))]
    left = [r for r in mine if "left" in r.getMessage()]
    assert len(left) == 1, [r.getMessage() for r in mine]
    assert left[0].levelno == logging.INFO
    assert all(r.exc_info is None and r.levelno < logging.ERROR for r in mine), [
        (r.name, r.levelname, r.getMessage()) for r in mine
    ]
