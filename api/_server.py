"""The HTTP server under the app: uvicorn, with what a service that faces untrusted clients needs.

uvicorn waits for a request's header for as long as the client likes, and its ``limit_concurrency``
counts a connection only once its header is complete: two hundred clients that send a header a byte a
minute hold two hundred connections for ever. :class:`ServeLimits` sets

* ``header_timeout_s``: a request's header must be complete this long after the connection opens (or,
  on a kept-alive connection, after the request's first byte), else 408 and the connection is closed;
* ``max_connections``: connections beyond it are answered 503 (``Retry-After``) and closed at once;
* ``body_idle_s`` / ``body_s``: the request body's timeouts, enforced in the app (``api/_edge.py``).

The protocol is uvicorn's own httptools protocol with a timer and a count added
(:class:`_GuardedHttp`); the server's socket is bound here before uvicorn starts, so that a port in
use or an address that is not this machine's is one clear error (:class:`ListenError`).
"""

from __future__ import annotations

import asyncio
import errno
import logging
import os
import socket
import time
from dataclasses import dataclass
from typing import Any

import uvicorn
from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

from api._errors import RETRY_AFTER_S, problem_bytes
from station.imageio import DEFAULT_MAX_DECODED_BYTES

log = logging.getLogger(__name__)


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


@dataclass(frozen=True)
class ServeLimits:
    """How much the service gives one client, and all of them."""

    header_timeout_s: float = 10.0
    body_idle_s: float = 10.0
    """The longest pause in a request body."""
    body_s: float = 120.0
    """The longest a request body may take from its first byte read."""
    max_connections: int = 128
    measure_slots: int = _cores()
    """``/measure`` decodes and measures at most this many images at a time (one per core) ..."""
    measure_queue: int = _cores()
    """... with at most this many more waiting; beyond, 503 with ``Retry-After``."""
    max_decoded_bytes: int = DEFAULT_MAX_DECODED_BYTES
    """An uploaded image's decoded size (width x height x channels x bytes per sample)."""

    def __post_init__(self) -> None:
        for name in ("header_timeout_s", "body_idle_s", "body_s"):
            if not 0 < getattr(self, name) < 3600:
                raise ValueError(f"{name} must be between 0 and 3600 s, got {getattr(self, name)}")
        if self.max_connections < 1 or self.measure_slots < 1 or self.measure_queue < 0:
            raise ValueError("max_connections and measure_slots must be at least 1, measure_queue at least 0")
        if self.max_decoded_bytes < 1:
            raise ValueError(f"max_decoded_bytes must be positive, got {self.max_decoded_bytes}")


class ListenError(OSError):
    """The server cannot listen where it was asked to; ``str()`` says why and what to do."""


def listen(host: str, port: int) -> socket.socket:
    """A TCP socket bound to ``host``:``port`` and listening (port 0: any free one)."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as exc:
        raise ListenError(
            f"cannot listen on {host}:{port}: {host!r} is not an address of this machine ({exc.strerror}); "
            "give --host 127.0.0.1, or one of its addresses"
        ) from None
    family, kind, proto, _, address = infos[0]
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if family == socket.AF_INET6:
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
        sock.bind(address)
        sock.listen(2048)
    except OSError as exc:
        sock.close()
        why = {
            errno.EADDRINUSE: "the port is in use (another station serve?): stop that server or give --port",
            errno.EACCES: "ports under 1024 need root: give --port 1024 or above",
            errno.EADDRNOTAVAIL: "that address is not one of this machine's: give --host 127.0.0.1",
        }.get(exc.errno or 0, exc.strerror or str(exc))
        raise ListenError(f"cannot listen on {host}:{port}: {why}") from None
    return sock


def _raw_problem(
    status: int, reason: str, detail: str, code: str, *, retry_after: int | None = None
) -> bytes:
    body = problem_bytes(status, detail, code)
    head = [
        f"HTTP/1.1 {status} {reason}",
        "content-type: application/problem+json",
        f"content-length: {len(body)}",
        "connection: close",
    ]
    if retry_after is not None:
        head.append(f"retry-after: {retry_after}")
    return ("\r\n".join(head) + "\r\n\r\n").encode() + body


class _GuardedHttp(HttpToolsProtocol):
    """uvicorn's httptools protocol with a header timeout and a connection limit (:class:`ServeLimits`)."""

    limits: ServeLimits = ServeLimits()
    _header_timer: asyncio.TimerHandle | None = None
    _refused = 0
    _refused_logged = 0.0

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        if len(self.connections) > self.limits.max_connections:
            self._refuse(transport)
            return
        self._arm_header_timer()

    def _refuse(self, transport: asyncio.Transport) -> None:
        cls = type(self)
        cls._refused += 1
        now = time.monotonic()
        if now - cls._refused_logged > 10:  # one line per 10 s under a flood
            log.warning(
                "%d connection(s) refused: %d open, the limit is %d",
                cls._refused,
                len(self.connections) - 1,
                self.limits.max_connections,
            )
            cls._refused, cls._refused_logged = 0, now
        detail = (
            f"the station has {self.limits.max_connections} connections open, its limit: "
            "try again in a moment, and close connections you no longer use"
        )
        retry = RETRY_AFTER_S["too_many_connections"]
        transport.write(
            _raw_problem(503, "Service Unavailable", detail, "too_many_connections", retry_after=retry)
        )
        transport.close()

    def _arm_header_timer(self) -> None:
        if self._header_timer is None:
            self._header_timer = self.loop.call_later(self.limits.header_timeout_s, self._header_timed_out)

    def _disarm_header_timer(self) -> None:
        if self._header_timer is not None:
            self._header_timer.cancel()
            self._header_timer = None

    def _header_timed_out(self) -> None:
        self._header_timer = None
        if self.transport.is_closing():
            return
        if self.cycle is None or self.cycle.response_complete:  # no response of this connection under way
            timeout = self.limits.header_timeout_s
            log.info("%s: no complete request header in %g s; answered 408", _peer(self.client), timeout)
            detail = (
                f"the request header was not complete within {self.limits.header_timeout_s:g} s: "
                "send the whole header at once"
            )
            self.transport.write(_raw_problem(408, "Request Timeout", detail, "request_timeout"))
        self.transport.close()

    def on_message_begin(self) -> None:
        super().on_message_begin()
        self._arm_header_timer()  # a kept-alive connection's next request: its header's clock starts

    def on_headers_complete(self) -> None:
        self._disarm_header_timer()
        super().on_headers_complete()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm_header_timer()
        super().connection_lost(exc)


def _peer(client: Any) -> str:
    return f"{client[0]}:{client[1]}" if client else "a client"


def protocol_for(limits: ServeLimits) -> type[asyncio.Protocol]:
    """The HTTP protocol class uvicorn instantiates per connection, with ``limits``."""
    return type("StationHttp", (_GuardedHttp,), {"limits": limits})


def server_config(app: Any, limits: ServeLimits, **options: Any) -> uvicorn.Config:
    """uvicorn's configuration for ``app`` with ``limits`` (``options``: any other of uvicorn's)."""
    return uvicorn.Config(
        app,
        http=protocol_for(limits),
        access_log=False,  # request lines carry the login URL's token
        log_config=None,  # uvicorn logs through the station's logging (stderr)
        lifespan="on",
        **options,
    )
