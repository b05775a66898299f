"""The operator page: static HTML, CSS and JavaScript from ``api/static`` (no build step), and the
login URL (``/?token=TOKEN``) that sets the token cookie and redirects to the bare page."""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, Request
from fastapi.responses import FileResponse, RedirectResponse, Response

from api._auth import COOKIE
from api._errors import ApiError

STATIC = Path(__file__).parent / "static"

router = APIRouter(include_in_schema=False)


@router.get("/favicon.ico")
async def favicon() -> FileResponse:
    """The station's icon (browsers ask for this path even when the page names its icon)."""
    return FileResponse(
        STATIC / "favicon.svg", media_type="image/svg+xml", headers={"Cache-Control": "max-age=86400"}
    )


@router.get("/")
async def page(request: Request, token: str | None = None) -> Response:
    if token is not None:
        access = request.app.state.access
        if not access.matches(token):
            raise ApiError(
                401, "the token in this URL is wrong: use the URL station serve printed", "bad_token"
            )
        response = RedirectResponse("/", status_code=303)
        response.set_cookie(COOKIE, token, httponly=True, samesite="strict", path="/")
        return response
    return FileResponse(STATIC / "index.html", media_type="text/html", headers={"Cache-Control": "no-store"})
