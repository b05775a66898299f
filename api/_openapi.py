"""The OpenAPI document lists every answer each route gives: its refusals as problem details, its
media types (``application/zip``, ``text/html``, images, CSV, event streams) and their headers.

Routes declare their own refusals with :func:`problems`; :func:`install` adds the answers every
operation can get from the edge before any route runs (400 for a Host that is not allowed, 405 with
``Allow`` for a method the path does not have, 408 for a request too slow to arrive, 503 when the
server has all the connections it takes) and the ``Problem`` schema they all refer to.
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi

from api._errors import PROBLEM_JSON
from api._models import Problem

PROBLEM_REF = {"$ref": "#/components/schemas/Problem"}

WHY = {
    400: "the Host header is not one this station answers to (bad_host), or a JSON body is not UTF-8 "
    "(bad_body)",
    401: "no token, or a wrong one (token_required, bad_token)",
    403: "a request with the login cookie that this station's own page did not make (cross_origin)",
    404: "no such session, prompt or file, or an id that does not have the pattern of one",
    405: "the path does not take this method; Allow lists those it takes",
    408: "the request's header or body did not arrive in time (request_timeout)",
    409: "the station's or the session's state does not allow it now",
    413: "the body is over the size limit (too_large)",
    415: "the body's Content-Type is not one this route takes (unsupported_type)",
    422: "the request, a parameter or the uploaded file is invalid; detail names it",
    502: "a device failed while answering (device_error): its message says which and what to check",
    503: "a part is unavailable for now: the record (record_unavailable), the station's worker "
    "(worker_unavailable), all measuring slots (busy) or all connections in use (too_many_connections)",
}

_HEADERS: dict[int, dict[str, Any]] = {
    401: {"WWW-Authenticate": {"description": "Bearer", "schema": {"type": "string"}}},
    405: {
        "Allow": {"description": "the methods the path takes", "required": True, "schema": {"type": "string"}}
    },
    503: {
        "Retry-After": {"description": "seconds to wait before trying again", "schema": {"type": "integer"}}
    },
}

EDGE = (400, 405, 408, 503)
"""What any operation can get before its route runs."""


def problem_response(status: int, description: str | None = None) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "description": description or WHY[status],
        "content": {PROBLEM_JSON: {"schema": PROBLEM_REF}},
    }
    if status in _HEADERS:
        doc["headers"] = _HEADERS[status]
    return doc


MOTION_403 = (
    "from another machine (``remote_motion``: only from the station itself unless"
    " ``--allow-remote-motion``), or a cookie request from another page"
)
"""The 403 of every route that moves the arm (``api._auth.motion_access``)."""
ARM_BUSY_409 = (
    "a session owns the arm, or it is already moving (``conflict``), a stop is latched"
    " (``stop_latched``: acknowledge it at the station), or another process holds the station"
)
"""The 409 of every route that moves the arm between sessions."""


def problems(*statuses: int, **described: str) -> dict[int | str, dict[str, Any]]:
    """``responses=`` of a route: a problem-details answer for each status (``described``: ``s409=...``
    gives a status its own description)."""
    out: dict[int | str, dict[str, Any]] = {s: problem_response(s) for s in statuses}
    for key, text in described.items():
        status = int(key.lstrip("s"))
        out[status] = problem_response(status, text)
    return out


def binary(media_type: str, description: str) -> dict[str, Any]:
    """A 200 answer whose body is a file of ``media_type``."""
    return {
        "description": description,
        "content": {media_type: {"schema": {"type": "string", "format": "binary"}}},
    }


def install(app: FastAPI) -> None:
    """Build the document once, with the edge's answers and the ``Problem`` schema added."""

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is not None:
            return app.openapi_schema
        doc = get_openapi(
            title=app.title,
            version=app.version,
            description=app.description,
            routes=app.routes,
        )
        schemas = doc.setdefault("components", {}).setdefault("schemas", {})
        schemas["Problem"] = Problem.model_json_schema()
        for item in doc.get("paths", {}).values():
            for operation in item.values():
                responses = operation.setdefault("responses", {})
                for status in EDGE:
                    responses.setdefault(str(status), problem_response(status))
                _problem_json_only(responses)
                for parameter in operation.get("parameters", []):
                    _not_null(parameter)
        app.openapi_schema = doc
        return doc

    app.openapi = openapi  # type: ignore[method-assign]


def _problem_json_only(responses: dict[str, Any]) -> None:
    """FastAPI documents its own 422 as ``application/json``; every refusal here is problem details."""
    for status, doc in responses.items():
        if status.startswith(("4", "5")):
            doc["content"] = {PROBLEM_JSON: {"schema": PROBLEM_REF}}


def _not_null(parameter: dict[str, Any]) -> None:
    """An optional header or query parameter is absent when not given, never ``null`` (which a client
    could only send as the text "null"): ``anyOf: [X, null]`` becomes ``X``."""
    schema = parameter.get("schema", {})
    options = schema.get("anyOf")
    if isinstance(options, list):
        kept = [o for o in options if o.get("type") != "null"]
        if len(kept) == 1:
            del schema["anyOf"]
            schema.update(kept[0])
