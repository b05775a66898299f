"""Access control: this API moves a robot arm.

Mutations, prompt answers and event streams need the token: ``Authorization: Bearer TOKEN`` or the
``station_token`` cookie (a browser's EventSource cannot send headers). The cookie is set by opening
the page's login URL (``/?token=TOKEN``), which redirects to the bare URL. GET endpoints other than
streams are open while the server is bound to loopback and ``open_reads`` is on; otherwise they need
the token too. Tokens are compared in constant time and never logged.
"""

from __future__ import annotations

import hmac
import ipaddress
import os
import secrets
from dataclasses import dataclass

from fastapi import Request

from api._errors import ApiError

COOKIE = "station_token"
TOKEN_ENV = "STATION_API_TOKEN"
MIN_TOKEN_CHARS = 16


def is_loopback(host: str) -> bool:
    """Whether binding to ``host`` keeps the server on this machine (127.0.0.0/8, ::1, localhost)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def resolve_token(configured: str | None) -> tuple[str, bool]:
    """The token: the configuration's, else ``$STATION_API_TOKEN``, else a new random one.
    Returns ``(token, generated)``."""
    if configured:
        return configured, False
    env = os.environ.get(TOKEN_ENV, "").strip()
    if env:
        if len(env) < MIN_TOKEN_CHARS:
            raise ValueError(
                f"{TOKEN_ENV} is {len(env)} characters long; use at least {MIN_TOKEN_CHARS} "
                "(e.g. python -c 'import secrets; print(secrets.token_urlsafe(32))')"
            )
        return env, False
    return secrets.token_urlsafe(32), True


@dataclass(frozen=True)
class Access:
    """The token and whether GET endpoints are open without it."""

    token: str
    open_reads: bool

    def matches(self, candidate: str | None) -> bool:
        return candidate is not None and hmac.compare_digest(candidate.encode(), self.token.encode())

    def presented(self, request: Request) -> str | None:
        header = request.headers.get("authorization", "")
        scheme, _, value = header.partition(" ")
        if scheme.lower() == "bearer" and value.strip():
            return value.strip()
        return request.cookies.get(COOKIE)

    def check(self, request: Request) -> None:
        token = self.presented(request)
        if token is None:
            raise ApiError(
                401,
                "this endpoint needs the station's API token: send 'Authorization: Bearer TOKEN', "
                "or open the login URL that station serve printed",
                "token_required",
            )
        if not self.matches(token):
            raise ApiError(
                401, "the API token is wrong: use the one station serve printed or configured", "bad_token"
            )


def _access(request: Request) -> Access:
    access: Access = request.app.state.access
    return access


# The dependencies are coroutines on purpose: FastAPI runs a plain function in its thread pool, a hop to
# another thread and back on every request for a check that takes microseconds.


async def require_token(request: Request) -> None:
    """Dependency of mutations, prompt answers and event streams."""
    _access(request).check(request)


async def read_access(request: Request) -> None:
    """Dependency of GET endpoints: open on loopback with ``open_reads``, else the token."""
    access = _access(request)
    if not access.open_reads:
        access.check(request)
