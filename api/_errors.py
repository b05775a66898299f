"""Errors as RFC 9457 problem details, mapped in one place from the project's exception types.

Every error response is ``application/problem+json``: ``{"type", "title", "status", "detail", "code"}``
(``code``: the exception's stable ``code`` where it has one, else a name derived from its class).
The table below is the only place where an exception becomes an HTTP status.
"""

from __future__ import annotations

import json
import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.requests import ClientDisconnect
from starlette.routing import Match

from api._service import ConflictError, ImportArchiveError, NotAvailableError, WorkerError
from station.arm_route import RouteRejectedError
from station.config import ConfigurationError
from station.devices import DeviceError, MotionRejectedError, StopLatchedError
from station.imageio import ImageFileError
from station.local_ack import RemoteAcknowledgementError
from station.plans import PlanError
from station.prompts import InvalidAnswerError, PromptBusyError, PromptError, UnknownPromptError
from station.record import (
    ImportRefusedError,
    RecordError,
    RecordNotFoundError,
    RecordUnavailableError,
    SessionLockError,
)
from station.runner import PreflightError, SessionError
from station.scale_calibration import NothingToRevertError, ScaleCalibrationError
from station.teach import CalibrationRefusedError, CalibrationSessionInvalidError, TeachError

log = logging.getLogger(__name__)

PROBLEM_JSON = "application/problem+json"
PROBLEM_BASE = "https://station.invalid/problems/"

#: Exception type -> (HTTP status, code). The first matching entry wins (most specific first).
STATUS_OF: tuple[tuple[type[Exception], int, str], ...] = (
    (RecordNotFoundError, 404, "session_not_found"),
    (NothingToRevertError, 409, "nothing_to_revert"),
    (ScaleCalibrationError, 422, "scale_calibration_error"),
    (SessionLockError, 409, "station_busy"),
    (ImportArchiveError, 422, "bad_archive"),
    (ImportRefusedError, 422, "import_refused"),
    (PreflightError, 422, "preflight_failed"),
    (ConflictError, 409, "conflict"),
    (WorkerError, 503, "worker_unavailable"),
    (NotAvailableError, 409, "not_available"),
    (SessionError, 409, "session_error"),
    (UnknownPromptError, 409, "prompt_not_open"),
    (InvalidAnswerError, 422, "invalid_readings"),
    (PromptBusyError, 409, "prompt_busy"),
    (PromptError, 409, "prompt_error"),
    (ImageFileError, 422, "bad_image"),
    (RecordUnavailableError, 503, "record_unavailable"),
    (PlanError, 422, "invalid_parameters"),
    (ConfigurationError, 422, "configuration_error"),
    (RecordError, 422, "record_error"),
    (RouteRejectedError, 422, "route_rejected"),
    (RemoteAcknowledgementError, 403, "remote_acknowledgement"),
    (StopLatchedError, 409, "stop_latched"),
    (MotionRejectedError, 422, "motion_rejected"),
    (CalibrationSessionInvalidError, 422, "calibration_session_invalid"),
    (CalibrationRefusedError, 409, "calibration_refused"),
    (TeachError, 422, "teach_failed"),
    (DeviceError, 502, "device_error"),
)

TITLES = {
    400: "Bad request",
    401: "Unauthorized",
    403: "Forbidden",
    404: "Not found",
    405: "Method not allowed",
    408: "Request timeout",
    409: "Conflict",
    413: "Content too large",
    415: "Unsupported media type",
    422: "Unprocessable content",
    500: "Internal server error",
    502: "Bad gateway",
    503: "Service unavailable",
}


RETRY_AFTER_S = {"record_unavailable": 2, "busy": 1, "too_many_connections": 1}
"""``Retry-After`` (seconds) of the 503 answers, by code: what is unavailable comes back by itself."""


def problem_body(status: int, detail: str, code: str, **extra: Any) -> dict[str, Any]:
    return {
        "type": PROBLEM_BASE + code,
        "title": TITLES.get(status, "Error"),
        "status": status,
        "detail": detail,
        "code": code,
        **extra,
    }


def problem_bytes(status: int, detail: str, code: str) -> bytes:
    """A problem-details body, for answers given below the app (the server, the edge middlewares)."""
    return json.dumps(problem_body(status, detail, code)).encode()


def problem(
    status: int, detail: str, code: str, *, headers: dict[str, str] | None = None, **extra: Any
) -> JSONResponse:
    """A problem-details response (401 with ``WWW-Authenticate``, 503 with ``Retry-After``)."""
    head = dict(headers or {})
    if status == 401:
        head["WWW-Authenticate"] = 'Bearer realm="station"'
    if status == 503 and code in RETRY_AFTER_S:
        head.setdefault("Retry-After", str(RETRY_AFTER_S[code]))
    return JSONResponse(
        problem_body(status, detail, code, **extra), status_code=status, media_type=PROBLEM_JSON, headers=head
    )


def status_of(exc: BaseException) -> tuple[int, str]:
    for kind, status, code in STATUS_OF:
        if isinstance(exc, kind):
            return status, code
    return 500, "internal_error"


class ApiError(Exception):
    """An HTTP-level refusal raised by the routers themselves (401, 413, 415 ...)."""

    def __init__(self, status: int, detail: str, code: str, *, headers: dict[str, str] | None = None) -> None:
        super().__init__(detail)
        self.status = status
        self.detail = detail
        self.code = code
        self.headers = headers


FASTAPI_BODY_ERROR = "There was an error parsing the body"
"""FastAPI's 400 for a JSON body it cannot decode (JSON syntax errors are 422 ``invalid_request``)."""
METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")


def allowed_methods(request: Request) -> str:
    """The methods some route of the request's path takes (Starlette's own ``Allow`` names only the
    first such route's: ``GET`` and ``POST`` of one path are two routes)."""
    routes = request.app.router.routes
    allowed = [
        method
        for method in METHODS
        if any(route.matches({**request.scope, "method": method})[0] is Match.FULL for route in routes)
    ]
    return ", ".join(allowed)


def install(app: FastAPI) -> None:
    """Register the mapping on ``app``: domain exceptions, request validation, HTTP errors."""

    async def domain(request: Request, exc: Exception) -> JSONResponse:
        status, code = status_of(exc)
        if isinstance(exc, ImageFileError):
            return problem(status, exc.reason, "bad_image")
        extra: dict[str, Any] = {}
        if isinstance(exc, PreflightError | RouteRejectedError):
            extra["problems"] = exc.problems
        return problem(status, str(exc), code, **extra)

    async def api_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, ApiError)
        return problem(exc.status, exc.detail, exc.code, headers=exc.headers)

    async def validation(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, RequestValidationError)
        errors = exc.errors()
        parts = []
        for e in errors:
            where = ".".join(str(x) for x in e.get("loc", ()) if x != "body") or "(request)"
            parts.append(f"{where}: {e.get('msg')}")
        return problem(422, "; ".join(parts) or "invalid request", "invalid_request")

    async def http_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, StarletteHTTPException)
        code = {404: "not_found", 405: "method_not_allowed"}.get(exc.status_code, f"http_{exc.status_code}")
        detail, headers = str(exc.detail), dict(exc.headers or {})
        if exc.status_code == 400 and detail == FASTAPI_BODY_ERROR:  # not JSON's syntax: its bytes
            detail = "the body cannot be read as JSON text (it is not UTF-8): send UTF-8 JSON"
            code = "bad_body"
        if exc.status_code == 405:
            headers["Allow"] = allowed_methods(request)
            detail = f"{request.method} is not allowed here; allowed: {headers['Allow']}"
        return problem(exc.status_code, detail, code, headers=headers)

    async def client_left(request: Request, exc: Exception) -> Response:
        # the client hung up during its request body: api/_edge.py has logged it once; nobody to answer
        return Response(status_code=400)

    async def unexpected(request: Request, exc: Exception) -> JSONResponse:
        log.error("unexpected error on %s %s: %s", request.method, request.url.path, exc, exc_info=exc)
        return problem(500, f"unexpected {type(exc).__name__}: {exc}", "internal_error")

    for kind, _status, _code in STATUS_OF:
        app.add_exception_handler(kind, domain)
    app.add_exception_handler(ApiError, api_error)
    app.add_exception_handler(ClientDisconnect, client_left)
    app.add_exception_handler(RequestValidationError, validation)
    app.add_exception_handler(StarletteHTTPException, http_error)
    app.add_exception_handler(Exception, unexpected)
