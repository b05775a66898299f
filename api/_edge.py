"""The HTTP edge, before any route: which Host names are served, how long a request body may take, and
clients that leave.

Three pure ASGI middlewares (no FastAPI types; each answers with the same problem details as the
routes, ``api/_errors.py``):

* :class:`HostCheck`: a request whose ``Host`` is not an allowed name is 400 before routing. A web
  page that rebinds its own name to 127.0.0.1 (DNS rebinding) reaches the server with that name in
  ``Host``, so an allow-list of the names the station is opened by closes it: the loopback names,
  the bound address, and what ``--allowed-host`` / ``STATION_ALLOWED_HOSTS`` add.
* :class:`BodyDeadline`: a request body must keep coming (no pause longer than ``body_idle_s``) and be
  complete within ``body_s`` of its first read; otherwise 408 and the connection is closed. (The
  header's own timeout is the server's: ``api/_server.py``.) A client that hangs up during its body
  is one log line here; the routes then see a quiet disconnect, never a traceback.
* :class:`ClientsLeaving`: a client leaving an event stream is not a server error (see its docstring).
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import anyio

from api._errors import problem_bytes

log = logging.getLogger(__name__)

LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
TIMED_OUT = "station.body_timed_out"
"""Scope key set when :class:`BodyDeadline` has answered 408: the route's own error is dropped."""


def normalize_host(name: str) -> str:
    """``name`` as compared: lower case, no brackets around an IPv6 address, no trailing dot."""
    host = name.strip().lower().rstrip(".")
    return host[1:-1] if host.startswith("[") and host.endswith("]") else host


def host_of(header: str) -> str:
    """The host name of a ``Host`` header value (``[::1]:8465`` -> ``::1``, ``Localhost.`` ->
    ``localhost``)."""
    value = header.strip()
    if value.startswith("["):
        return normalize_host(value[: value.find("]") + 1] if "]" in value else value)
    return normalize_host(value.rsplit(":", 1)[0] if value.count(":") == 1 else value)


@dataclass(frozen=True)
class AllowedHosts:
    """The host names a request's ``Host`` header may carry."""

    names: frozenset[str]

    @classmethod
    def of(cls, extra: Iterable[str] = (), *, bound: str | None = None) -> AllowedHosts:
        """The loopback names, ``extra`` and ``bound`` (the address the server listens on, unless a
        wildcard: an IP address literal cannot be rebound)."""
        names = {normalize_host(n) for n in (*LOOPBACK_NAMES, *extra) if n.strip()}
        if bound:
            try:
                address = ipaddress.ip_address(normalize_host(bound))
            except ValueError:
                names.add(normalize_host(bound))
            else:
                if not address.is_unspecified:
                    names.add(str(address))
        return cls(frozenset(names))

    def allows(self, host_header: str | None) -> bool:
        return host_header is not None and host_of(host_header) in self.names

    def listed(self) -> str:
        return ", ".join(f"[{n}]" if ":" in n else n for n in sorted(self.names))


def _header(scope: Any, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key == name:
            text: str = value.decode("latin-1")
            return text
    return None


async def _answer(send: Any, status: int, detail: str, code: str, *, close: bool = False) -> None:
    body = problem_bytes(status, detail, code)
    headers = [(b"content-type", b"application/problem+json"), (b"content-length", str(len(body)).encode())]
    if close:
        headers.append((b"connection", b"close"))
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


class HostCheck:
    """400 for a ``Host`` header that is not allowed, before routing."""

    def __init__(self, app: Any, hosts: AllowedHosts) -> None:
        self.app = app
        self.hosts = hosts

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        host = _header(scope, b"host")
        if self.hosts.allows(host):
            await self.app(scope, receive, send)
            return
        await _answer(
            send,
            400,
            f"this station does not answer to the host name {host!r} (it answers to {self.hosts.listed()}): "
            "open the URL station serve printed, or start it with --allowed-host NAME for a name of this "
            "machine",
            "bad_host",
            close=True,
        )


class BodyDeadline:
    """408 for a request body that stalls or takes too long; one log line for a client that leaves
    before its body is complete."""

    def __init__(self, app: Any, *, idle_s: float, total_s: float) -> None:
        self.app = app
        self.idle_s = idle_s
        self.total_s = total_s

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        complete = False
        answered = False
        deadline: float | None = None

        async def guarded_receive() -> Any:
            nonlocal complete, answered, deadline
            if complete or answered:
                return await receive() if complete else {"type": "http.disconnect"}
            now = time.monotonic()
            if deadline is None:  # the body's clock starts at its first read (a queued upload waits)
                deadline = now + self.total_s
            wait = min(self.idle_s, deadline - now)
            try:
                message = await asyncio.wait_for(receive(), max(wait, 0.0))
            except TimeoutError:
                answered = True
                scope.setdefault("state", {})[TIMED_OUT] = True
                what = "stalled" if wait >= self.idle_s else "was not complete in time"
                log.info("%s %s: the request body %s; answered 408", scope["method"], scope["path"], what)
                if not started:
                    await _answer(
                        send,
                        408,
                        f"the request body {what} (a pause over {self.idle_s:g} s, or over "
                        f"{self.total_s:g} s in all): send it again at once and without pauses",
                        "request_timeout",
                        close=True,
                    )
                return {"type": "http.disconnect"}
            if message["type"] == "http.disconnect":
                answered = True
                what = f"{scope['method']} {scope['path']}"
                log.info("%s: the client left before its request body was complete", what)
            elif not message.get("more_body", False):
                complete = True
            return message

        started = False

        async def guarded_send(message: Any) -> None:
            nonlocal started
            if answered and not complete:
                return  # the 408 is sent, or the client has gone: the route's own answer is dropped
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        await self.app(scope, guarded_receive, guarded_send)


_GONE = (anyio.BrokenResourceError, anyio.ClosedResourceError)


class ClientsLeaving:
    """A client leaving an event stream is not a server error.

    When a client disconnects while an SSE response still has an event in flight, FastAPI's own
    keep-alive task (``fastapi.routing``, SSE) finds its output stream closed and its task group raises
    ``BrokenResourceError`` in an exception group after the response has started (fastapi discussion
    #15725): logged as an unexpected error and "Exception in ASGI application" for a normal
    disconnect. This drops exactly that, once the response has started: an exception group whose
    every exception is anyio's broken or closed stream. Anything else still propagates.
    """

    def __init__(self, app: Any) -> None:
        self.app = app

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = False

        async def send_tracking(message: Any) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, receive, send_tracking)
        except BaseExceptionGroup as group:
            _, rest = group.split(_GONE)
            if not started or rest is not None:
                raise
            log.debug("%s: the client left during the response", scope.get("path"))
