"""The application factory: routers over one :class:`StationService` kept on ``app.state``, behind the
edge's checks (``api/_edge.py``)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

from api import _errors, _openapi
from api._auth import Access
from api._edge import AllowedHosts, BodyDeadline, ClientsLeaving, HostCheck
from api._gate import DecodeGate
from api._page import STATIC
from api._page import router as page_router
from api._routes_events import router as events_router
from api._routes_plans import router as plans_router
from api._routes_prompt import router as prompt_router
from api._routes_safety import router as safety_router
from api._routes_scale_calibration import router as scale_calibration_router
from api._routes_sessions import router as sessions_router
from api._routes_station import router as station_router
from api._routes_teach import router as teach_router
from api._server import ServeLimits
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


def create_app(
    service: StationService,
    access: Access,
    *,
    close_service: bool = True,
    limits: ServeLimits | None = None,
    hosts: AllowedHosts | None = None,
) -> FastAPI:
    """The FastAPI app serving ``service``; ``access`` holds the token and whether reads are open,
    ``limits`` the request timeouts and ``/measure``'s slots (the server's own are applied by
    ``api/_server.py``), ``hosts`` the Host names served (default: the loopback names). With
    ``close_service`` the service is closed (session stopped, devices closed) at shutdown."""
    lim = limits or ServeLimits()

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
        description="Sessions, measurements, operator prompts and live events of the station. Everything "
        "but /health and /access need the station's token (Bearer, or the cookie the login URL sets; a "
        "cookie request must come from the station's own page), unless station serve --public-read opens "
        "the reads.",
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
    app.state.limits = lim
    app.state.measure_gate = DecodeGate(lim.measure_slots, lim.measure_queue)
    app.state.stopping = asyncio.Event()
    _errors.install(app)
    # the last added runs first: the Host check before anything else, then the body's deadlines
    app.add_middleware(ClientsLeaving)
    app.add_middleware(BodyDeadline, idle_s=lim.body_idle_s, total_s=lim.body_s)
    app.add_middleware(HostCheck, hosts=hosts or AllowedHosts.of())
    for router in (
        station_router,
        teach_router,
        safety_router,
        plans_router,
        scale_calibration_router,
        sessions_router,
        prompt_router,
        events_router,
        page_router,
    ):
        app.include_router(router)
    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    _openapi.install(app)
    return app
