"""Access control: this API moves a robot arm, and its reads show the station's data.

Every route that returns the station's data (sessions, events, images, exports, reports, the camera,
``/station``) needs the token, as mutations do: ``Authorization: Bearer TOKEN`` or the
``station_token`` cookie (a browser's EventSource cannot send headers), which opening the page's
login URL (``/?token=TOKEN``) sets before redirecting to the bare URL. ``/health``, the page itself
and the OpenAPI document stay open. ``public_read`` (``station serve --public-read``, for a trusted
network) opens the reads again, never the event streams nor a mutation.

The cookie travels with any request the browser makes to this host, whatever page makes it:
``SameSite=Strict`` does not separate two ports of one host. So a request authenticated by the cookie
alone must come from the page itself:

* a mutation needs an ``Origin`` equal to this service's own scheme, host and port (or, without an
  ``Origin``, ``Sec-Fetch-Site: same-origin``), else 403;
* a read is refused (403) when the browser says it comes from another site or another port of this
  one (``Sec-Fetch-Site: cross-site`` or ``same-site``) and is not a navigation: another page can show
  neither the camera nor a report in its own frame.

A request with a Bearer token is a script's: none of this applies. Tokens are compared in constant
time and never logged.
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


class TokenError(ValueError):
    """The configured token is unusable; ``str()`` says why and how to make a good one."""


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
    Returns ``(token, generated)``; TokenError for a token shorter than ``MIN_TOKEN_CHARS``."""
    for source, value in (
        ("the configuration's [api] token", configured),
        (TOKEN_ENV, os.environ.get(TOKEN_ENV)),
    ):
        token = (value or "").strip()
        if not token:
            continue
        if len(token) < MIN_TOKEN_CHARS:
            raise TokenError(
                f"the API token needs at least {MIN_TOKEN_CHARS} characters ({source} has {len(token)}): "
                "make one with python3 -c 'import secrets; print(secrets.token_urlsafe(32))'"
            )
        return token, False
    return secrets.token_urlsafe(32), True


@dataclass(frozen=True)
class Access:
    """The token, and whether reads are open without it (``--public-read``)."""

    token: str
    public_read: bool = False
    remote_motion: bool = False

    def matches(self, candidate: str | None) -> bool:
        return candidate is not None and hmac.compare_digest(candidate.encode(), self.token.encode())

    def presented(self, request: Request) -> tuple[str | None, bool]:
        """The token the request carries and whether it came as a Bearer header (else the cookie)."""
        header = request.headers.get("authorization", "")
        scheme, _, value = header.partition(" ")
        if scheme.lower() == "bearer" and value.strip():
            return value.strip(), True
        return request.cookies.get(COOKIE), False

    def check(self, request: Request, *, mutation: bool) -> None:
        """401 without the right token; 403 for a cookie request another page made (see the module)."""
        token, bearer = self.presented(request)
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
        if not bearer:
            (same_origin if mutation else not_embedded)(request)


def own_origin(request: Request) -> str:
    """This service's origin as the client addressed it: scheme, host and port (the ``Host`` header,
    which the edge has checked against the allowed names)."""
    return f"{request.url.scheme}://{request.headers.get('host', '')}".lower()


def same_origin(request: Request) -> None:
    """403 unless the request comes from this service's own page (``Origin``, else Fetch Metadata)."""
    origin = request.headers.get("origin")
    site = request.headers.get("sec-fetch-site")
    mine = own_origin(request)
    if origin is not None:
        if origin.lower().rstrip("/") == mine:
            return
        came = f"from {origin}"
    elif site == "same-origin":
        return
    else:
        came = "with no Origin header" + (f" (Sec-Fetch-Site: {site})" if site else "")
    raise ApiError(
        403,
        f"a request authenticated by the login cookie came {came}, not from this station's page at "
        f"{mine}: use the page, or send 'Authorization: Bearer TOKEN' from a script",
        "cross_origin",
    )


def not_embedded(request: Request) -> None:
    """403 for a cookie read another site or another port's page embeds or fetches (not a navigation)."""
    site = request.headers.get("sec-fetch-site")
    if site in ("cross-site", "same-site") and request.headers.get("sec-fetch-mode") != "navigate":
        raise ApiError(
            403,
            f"another page ({site}) asked for this with the login cookie; open it from the station's own "
            f"page at {own_origin(request)}, or send 'Authorization: Bearer TOKEN' from a script",
            "cross_origin",
        )


def _access(request: Request) -> Access:
    access: Access = request.app.state.access
    return access


# The dependencies are coroutines on purpose: FastAPI runs a plain function in its thread pool, a hop to
# another thread and back on every request for a check that takes microseconds.


async def require_token(request: Request) -> None:
    """Dependency of mutations and prompt answers: the token, and a cookie only from the page."""
    _access(request).check(request, mutation=True)


async def stream_access(request: Request) -> None:
    """Dependency of the event streams: the token always (``public_read`` does not open them)."""
    _access(request).check(request, mutation=False)


def peer_is_local(request: Request) -> bool:
    """Whether the connection comes from the station itself: its peer (the TCP connection's, never a
    header a client writes) a loopback address."""
    return request.client is not None and is_loopback(request.client.host)


def may_move(request: Request) -> bool:
    """Whether this client may make the arm move: from the station itself, or any client with
    ``station serve --allow-remote-motion``."""
    return _access(request).remote_motion or peer_is_local(request)


def check_motion(request: Request, what: str) -> None:
    """403 ``remote_motion`` for a client on another machine unless ``--allow-remote-motion``."""
    if not may_move(request):
        peer = request.client.host if request.client is not None else "an unknown address"
        raise ApiError(
            403,
            f"{what} moves the arm, and this request comes from {peer}, not from the station itself: "
            "start it from the station (its page at 127.0.0.1, or station run there), or restart the "
            "service with station serve --allow-remote-motion on a trusted network",
            "remote_motion",
        )


async def motion_access(request: Request) -> None:
    """Dependency of the routes that make the arm move: the token, and the station itself unless
    ``--allow-remote-motion`` (pause, stop and abort do not need it: stopping is always allowed)."""
    _access(request).check(request, mutation=True)
    check_motion(request, "this request")


async def read_access(request: Request) -> None:
    """Dependency of the routes that return the station's data: the token unless ``public_read``."""
    access = _access(request)
    if not access.public_read:
        access.check(request, mutation=False)
