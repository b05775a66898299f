"""``/api/v1/sessions``: create and start, list, read, control; results, figures, report, export, import."""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Callable
from typing import Any, Literal, TypeVar

from fastapi import APIRouter, Depends, Query, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import FileResponse, Response

from api._auth import check_motion, may_move, read_access, require_token
from api._deps import Files, Measures, Reads, SessionId, service_of
from api._errors import ApiError
from api._models import (
    ActionRequest,
    OutcomeModel,
    SessionCreate,
    SessionList,
    SessionModel,
    SessionPage,
    rendered,
    session_model,
)
from api._openapi import binary, problems
from api._overlay import measurement_headers
from api._routes_station import read_body, require_type
from station.kinds import KIND_NAMES, get_plan, table_rows

router = APIRouter(prefix="/api/v1/sessions")

MAX_IMPORT_BYTES = 512 * 1024 * 1024
_FIGURE_NAME = re.compile(r"[A-Za-z0-9_.-]{1,100}")
ZIP_TYPES = ("application/zip",)
T = TypeVar("T")

#: The refusals of every route of one session.
ONE = (401, 403, 404, 422, 503)


async def quick(request: Request, read: Callable[..., T], *args: Any, **kwargs: Any) -> T:
    """``read(*args, **kwargs)`` on the event loop when the record is SQLite's file (a millisecond: the
    thread pool's hop costs more), else in the thread pool."""
    if service_of(request).record_is_local:
        return read(*args, **kwargs)
    return await run_in_threadpool(read, *args, **kwargs)


SESSION_LINKS = {
    "GetSession": {
        "operationId": "get_api_v1_sessions__session_id__get",
        "parameters": {"session_id": "$response.body#/id"},
    },
    "ActOnSession": {
        "operationId": "act_api_v1_sessions__session_id__actions_post",
        "parameters": {"session_id": "$response.body#/id"},
    },
    "GetResults": {
        "operationId": "results_api_v1_sessions__session_id__results_get",
        "parameters": {"session_id": "$response.body#/id"},
    },
    "GetExport": {
        "operationId": "export_api_v1_sessions__session_id__export_zip_get",
        "parameters": {"session_id": "$response.body#/id"},
    },
}
"""Where a created or imported session's id leads (OpenAPI links, which stateful clients follow)."""


def drives_devices(kind: str) -> bool:
    """Whether sessions of ``kind`` drive the station's devices (an unknown kind: no; it is refused
    later with its own answer)."""
    return kind in KIND_NAMES and bool(get_plan(kind).needs)


@router.post(
    "",
    status_code=201,
    response_model=SessionModel,
    dependencies=[Depends(require_token)],
    responses={
        201: {"description": "the session, started", "links": SESSION_LINKS},
        **problems(
            401,
            409,
            503,
            s403="a session that drives the station's devices, asked for from another machine "
            "(``remote_motion``: only from the station itself unless ``--allow-remote-motion``), or a "
            "cookie request from another page",
            s422="an unknown kind or a bad parameter (nothing created), or pre-flight found problems "
            "(preflight_failed, with problems; nothing moved)",
        ),
    },
)
async def create(request: Request, body: SessionCreate) -> Response:
    """Create a session and start it (409 while another one runs). One that drives the station's devices
    (the arm, the table) only from the station itself unless ``station serve --allow-remote-motion``."""
    service = service_of(request)
    if drives_devices(body.kind):
        check_motion(request, f"a {body.kind} session")
    view = await run_in_threadpool(service.create_session, body.kind, body.params, body.set)
    return rendered(session_model(view), 201)


@router.get(
    "",
    response_model=SessionList,
    dependencies=[Depends(read_access)],
    responses=problems(401, 403, 422, 503),
)
async def list_sessions(
    request: Request,
    reads: Reads,
    limit: int = Query(50, ge=1, le=1000),
    offset: int = Query(0, ge=0, le=10**9),
) -> Response:
    # quick reads (the service's cache while a session runs, else a millisecond of SQLite, WAL: never
    # waiting on the runner) run on the loop: a hop to the thread pool and back costs more than the read;
    # a database server's in the thread pool (one that went away may keep a connection waiting)
    views, total = await quick(request, reads.list_sessions, limit=limit, offset=offset)
    return rendered(SessionPage.model_construct(items=[session_model(v) for v in views], total=total))


@router.post(
    "/import",
    status_code=201,
    response_model=SessionModel,
    dependencies=[Depends(require_token)],
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {"application/zip": {"schema": {"type": "string", "format": "binary"}}},
        }
    },
    responses={
        201: {"description": "the imported session", "links": SESSION_LINKS},
        **problems(
            401, 403, 409, 413, 415, 503, s422="not an exported session, or one the record has already"
        ),
    },
)
async def import_session(request: Request, files: Files, reads: Reads) -> Response:
    """Import a session from a zip written by ``/export.zip`` (or a zipped ``station export`` folder);
    the body is the zip (``Content-Type: application/zip``)."""
    require_type(request, ZIP_TYPES)
    data = await read_body(request, MAX_IMPORT_BYTES)
    row = await run_in_threadpool(files.import_zip, data, max_bytes=MAX_IMPORT_BYTES * 4)
    return rendered(session_model(await run_in_threadpool(reads.get_session, row.id)), 201)


@router.get(
    "/{session_id}",
    response_model=SessionModel,
    dependencies=[Depends(read_access)],
    responses=problems(*ONE),
)
async def get(request: Request, reads: Reads, session_id: SessionId) -> Response:
    return rendered(session_model(await quick(request, reads.get_session, session_id)))


@router.post(
    "/{session_id}/actions",
    status_code=201,
    response_model=SessionModel,
    dependencies=[Depends(require_token)],
    responses=problems(
        401,
        404,
        422,
        503,
        s403="resume of a session that drives the station's devices from another machine "
        "(``remote_motion``), or a cookie request from another page",
        s409="the session's state does not allow the action",
    ),
)
async def act(request: Request, session_id: SessionId, body: ActionRequest) -> Response:
    """pause, resume (also continues an interrupted session), stop, abort; 409 when the state forbids it.
    Pause, stop and abort from anywhere with the token; resume as a start (``create``)."""
    if body.action == "resume" and not may_move(request):
        kind = (await quick(request, service_of(request).get_session, session_id)).row.kind
        if drives_devices(kind):
            check_motion(request, f"resuming a {kind} session")
    view = await run_in_threadpool(service_of(request).act, session_id, body.action)
    return rendered(session_model(view), 201)


@router.get(
    "/{session_id}/results",
    response_model=None,
    dependencies=[Depends(read_access)],
    responses={
        200: {
            "description": "the outcome (JSON), or its table (CSV)",
            "model": OutcomeModel,
            "content": {"text/csv": {"schema": {"type": "string"}}},
        },
        **problems(*ONE, s409="the session has no table of results (format=csv)"),
    },
)
async def results(session_id: SessionId, files: Files, format: Literal["json", "csv"] = "json") -> Any:
    """``station run --json``'s object; ``?format=csv``: the per-position (validation) or per-cycle
    (repeatability) table."""
    outcome = await run_in_threadpool(files.results, session_id)
    if format == "json":
        return rendered(outcome)
    rows = table_rows(outcome.kind, outcome.results)
    if not rows:
        raise ApiError(
            409,
            f"session {outcome.id} ({outcome.kind}, {outcome.state}) has no table of results",
            "no_table",
        )
    buf = io.StringIO()
    columns = list(dict.fromkeys(k for row in rows for k in row))  # every row's keys, in order of first use
    writer = csv.DictWriter(buf, fieldnames=columns, restval="", lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return Response(
        buf.getvalue(),
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="{outcome.id}-{outcome.kind}.csv"'},
    )


REPORT_409 = "the session has not ended: its report is written once it has"


@router.get(
    "/{session_id}/figures/{name}",
    dependencies=[Depends(read_access)],
    response_class=FileResponse,
    responses={
        200: {
            "description": "the figure",
            "content": {
                t: {"schema": {"type": "string", "format": "binary"}} for t in ("image/png", "image/svg+xml")
            },
        },
        **problems(*ONE, s409=REPORT_409),
    },
)
async def figure(session_id: SessionId, name: str, files: Files) -> FileResponse:
    """A figure of the session's report (``.png`` or ``.svg``), written on first request."""
    if not _FIGURE_NAME.fullmatch(name) or not name.endswith((".png", ".svg")):
        raise ApiError(404, f"no figure {name!r}: names end in .png or .svg", "not_found")
    folder = await run_in_threadpool(files.report_dir, session_id)
    path = folder / name
    if not path.is_file():
        names = sorted(p.name for p in folder.iterdir() if p.suffix in (".png", ".svg"))
        raise ApiError(
            404, f"no figure {name!r} for this session; it has: {', '.join(names) or 'none'}", "not_found"
        )
    return FileResponse(path)


@router.get(
    "/{session_id}/figures", dependencies=[Depends(read_access)], responses=problems(*ONE, s409=REPORT_409)
)
async def figures(session_id: SessionId, files: Files) -> dict[str, list[str]]:
    folder = await run_in_threadpool(files.report_dir, session_id)
    return {"figures": sorted(p.name for p in folder.iterdir() if p.suffix in (".png", ".svg"))}


_HEAD = re.compile(r"<head>", re.IGNORECASE)


@router.get(
    "/{session_id}/report.html",
    dependencies=[Depends(read_access)],
    response_class=Response,
    responses={
        200: {"description": "the report page", "content": {"text/html": {"schema": {"type": "string"}}}},
        **problems(*ONE, s409=REPORT_409),
    },
)
async def report(request: Request, session_id: SessionId, files: Files) -> Response:
    """The report's HTML page. Its links to the figure files are relative (``name.png``: they work in the
    report's folder on disk); served here, a ``<base>`` points them at the figure route."""
    folder = await run_in_threadpool(files.report_dir, session_id)
    pages = sorted(folder.glob("*.html"))
    if not pages:
        raise ApiError(409, "the report has no HTML page", "no_report")
    text = await run_in_threadpool(pages[0].read_text, encoding="utf-8")
    text = _HEAD.sub('<head><base href="figures/">', text, count=1)
    return Response(text, media_type="text/html")


@router.get(
    "/{session_id}/export.zip",
    dependencies=[Depends(read_access)],
    response_class=Response,
    responses={
        200: {
            **binary("application/zip", "the session as a self-contained folder (JSON, CSV, images), zipped"),
            "headers": {
                "Content-Disposition": {
                    "description": 'attachment; filename="ID.zip"',
                    "schema": {"type": "string"},
                }
            },
        },
        **problems(*ONE),
    },
)
async def export(session_id: SessionId, files: Files) -> Response:
    sid, data = await run_in_threadpool(files.export_zip, session_id)
    return Response(
        data,
        media_type="application/zip",
        headers={"Content-Disposition": f'attachment; filename="{sid}.zip"'},  # the record's own id
    )


@router.get(
    "/{session_id}/latest.png",
    dependencies=[Depends(read_access)],
    response_class=Response,
    responses={
        200: binary("image/png", "the latest capture, as PNG"),
        **problems(*ONE, s409="the session has no capture yet"),
    },
)
async def latest(session_id: SessionId, measurements: Measures, overlay: bool = True) -> Response:
    """The session's latest capture with its measurement drawn (the live view while it runs)."""
    picture = await run_in_threadpool(measurements.latest_capture_png, session_id, overlay=overlay)
    headers = {"Cache-Control": "no-store", **measurement_headers(picture.measurement)}
    return Response(picture.png, media_type="image/png", headers=headers)
