"""The application factory: routers over one :class:`StationService` kept on ``app.state``."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator
from typing import Any

import anyio
from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

from api import _errors
from api._auth import Access
from api._page import STATIC
from api._page import router as page_router
from api._routes_events import router as events_router
from api._routes_plans import router as plans_router
from api._routes_prompt import router as prompt_router
from api._routes_scale_calibration import router as scale_calibration_router
from api._routes_sessions import router as sessions_router
from api._routes_station import router as station_router
from api._service import StationService
from station import __version__

log = logging.getLogger(__name__)


class _NoQueryStrings(logging.Filter):
    """uvicorn's access log without query strings: the login URL's token never reaches a log, even where
    the access log is on (``access_log=False`` is the default of ``station serve``)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.args, tuple) and len(record.args) >= 3:
            path = record.args[2]
            if isinstance(path, str):
                record.args = (*record.args[:2], path.split("?", 1)[0], *record.args[3:])
        return True


ACCESS_FILTER = _NoQueryStrings()

_GONE = (anyio.BrokenResourceError, anyio.ClosedResourceError)


class _ClientsLeaving:
    """ASGI middleware: a client leaving an event stream is not a server error.

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


def create_app(service: StationService, access: Access, *, close_service: bool = True) -> FastAPI:
    """The FastAPI app serving ``service``; ``access`` holds the token and whether reads are open.
    With ``close_service`` the service is closed (session stopped, devices closed) at shutdown."""

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        try:
            yield
        finally:
            app.state.stopping.set()
            if close_service:
                await asyncio.get_running_loop().run_in_executor(None, service.close)

    app = FastAPI(
        title="Robot calibration station",
        version=__version__,
        description="Sessions, measurements, operator prompts and live events of the station. Mutations and "
        "event streams need the station's token (Bearer, or the cookie the login URL sets).",
        lifespan=lifespan,
        openapi_url="/api/v1/openapi.json",
        docs_url="/api/v1/docs",
        redoc_url=None,
    )
    access_logger = logging.getLogger("uvicorn.access")
    if ACCESS_FILTER not in access_logger.filters:
        access_logger.addFilter(ACCESS_FILTER)
    app.state.service = service
    app.state.access = access
    app.state.stopping = asyncio.Event()
    _errors.install(app)
    app.add_middleware(_ClientsLeaving)
    for router in (
        station_router,
        plans_router,
        scale_calibration_router,
        sessions_router,
        prompt_router,
        events_router,
        page_router,
    ):
        app.include_router(router)
    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    return app
