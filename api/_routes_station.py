"""``/api/v1/health``, ``/api/v1/station``, ``/api/v1/station/robot`` (and its ``to-reference``),
``/api/v1/camera/snapshot.png``, ``/api/v1/measure``."""

from __future__ import annotations

import struct
from typing import Any

from fastapi import APIRouter, Depends, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response
from pydantic import BaseModel

from api._auth import Access, may_move, motion_access, peer_is_local, read_access, require_token
from api._deps import Measures, Reads, service_of
from api._errors import ApiError
from api._gate import DecodeGate
from api._models import AccessModel, Health, StationModel, rendered
from api._openapi import ARM_BUSY_409, MOTION_403, binary, problems
from api._overlay import measurement_headers
from station import __version__
from station.arm_route import ArmStatus, ToReferenceResult
from station.imageio import DEFAULT_MAX_BYTES, ImageLimits, read_header
from station.vision import field_names

router = APIRouter(prefix="/api/v1")

IMAGE_TYPES = ("image/png", "image/tiff", "image/jpeg")
MAX_UPLOAD_BYTES = DEFAULT_MAX_BYTES


@router.get("/health", response_model=Health, summary="liveness (no token)")
async def health() -> Health:
    return Health(version=__version__)


@router.get("/access", response_model=AccessModel, summary="what this client may do (no token needed)")
async def access(request: Request) -> AccessModel:
    """Whether the request carries the station's token (header or the login cookie) and whether reads are
    open without it: the page says it is read-only, or that it needs the login URL, before anything fails."""
    granted: Access = request.app.state.access
    token, _ = granted.presented(request)
    return AccessModel(
        authenticated=granted.matches(token),
        open_reads=granted.public_read,
        local=peer_is_local(request),
        motion=may_move(request),
    )


@router.get(
    "/station", response_model=StationModel, dependencies=[Depends(read_access)], responses=problems(401, 403)
)
async def station(reads: Reads) -> Response:
    """Configuration (secrets redacted), devices' identities and states from the cached snapshot."""
    return rendered(StationModel.model_construct(**reads.station()))


@router.get(
    "/camera/snapshot.png",
    dependencies=[Depends(read_access)],
    response_class=Response,
    responses={
        200: binary("image/png", "the frame, as PNG"),
        **problems(401, 403, 422, 503, s409="a session owns the camera, or the station has none"),
    },
)
async def snapshot(measurements: Measures, overlay: bool = False) -> Response:
    """A frame from the camera (optionally with the measurement drawn on it); 409 while a session owns
    the camera: its latest capture is at ``/api/v1/sessions/{id}/latest.png`` then. A frame the
    measurement refuses (no crossing in view) is still a 200 frame: with ``overlay`` the refusal is
    written under it and sent beside it (``X-Measurement-Ok: false``, ``X-Measurement-Code``,
    ``X-Measurement-Error``); ``X-Measurement`` carries its numbers as JSON (``ok``, ``center_px``,
    ``center_mm``, ``code``, ``error``)."""
    picture = await run_in_threadpool(measurements.snapshot_png, overlay=overlay)
    headers = {"Cache-Control": "no-store", **measurement_headers(picture.measurement)}
    return Response(picture.png, media_type="image/png", headers=headers)


@router.get(
    "/station/robot",
    response_model=ArmStatus,
    dependencies=[Depends(read_access)],
    responses=problems(401, 403, 502, 503, s409="a session (or the arm's route) owns the arm"),
)
async def robot(request: Request) -> Response:
    """Where the arm is against its reference pose (``at_reference``) and the route ``to-reference``
    would take from here with every problem the driver's checks find in it; nothing moves."""
    return rendered(await run_in_threadpool(service_of(request).robot))


@router.post(
    "/station/robot/to-reference",
    response_model=ToReferenceResult,
    dependencies=[Depends(motion_access)],
    responses=problems(
        401,
        502,
        503,
        s403=MOTION_403,
        s409=ARM_BUSY_409,
        s422="the route is refused by the driver's checks; nothing moved (``problems``)",
    ),
)
async def to_reference(request: Request) -> Response:
    """Take the arm to its reference pose from wherever it is: through the lift pose unless it is within
    one joint step, every move within the driver's step limit and checked (limits, step, keep-out) from
    the arm's commanded position before the first is sent; answers once it has arrived, with the
    ``moves`` sent and the ``final_pose``."""
    return rendered(await run_in_threadpool(service_of(request).to_reference))


class AcknowledgedModel(BaseModel):
    """``acknowledged``: whether a stop was latched (and is released now); ``reason``: what latched it."""

    acknowledged: bool
    reason: str | None


@router.post(
    "/station/robot/acknowledge",
    response_model=AcknowledgedModel,
    dependencies=[Depends(require_token)],
    responses=problems(
        401,
        502,
        503,
        s403="not from the station itself (``remote_acknowledgement``), or a cookie request from another"
        " page",
        s409="a session runs (or the arm is on its way)",
    ),
)
async def acknowledge(request: Request) -> AcknowledgedModel:
    """Release the robot's stop latch (set by a stop, an abort, an E-stop or a controller error) for a
    person at the station: only from the station itself (the connection's peer a loopback address: the
    page opened on the station, or a script run there), never from another machine, whatever token it
    holds; ``station robot --config F acknowledge`` at the station's terminal does the same."""
    peer = request.client.host if request.client is not None else None
    done = await run_in_threadpool(service_of(request).acknowledge_stop, peer)
    return AcknowledgedModel.model_validate(done)


def require_type(request: Request, accepted: tuple[str, ...]) -> None:
    """415 unless the body's declared Content-Type is one of ``accepted``: a web page's no-cors
    request can only send text/plain or a form, so an upload route never reads those."""
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if ctype not in accepted:
        raise ApiError(
            415,
            f"content type {ctype or '(none)'!r} is not accepted here; send {', '.join(accepted)}",
            "unsupported_type",
        )


def check_declared_size(request: Request, max_bytes: int) -> None:
    """413 for a declared ``Content-Length`` over ``max_bytes``, before anything is read."""
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > max_bytes:
        raise ApiError(
            413, f"the body is {int(declared)} bytes, over the {max_bytes} byte limit", "too_large"
        )


async def read_body(request: Request, max_bytes: int) -> bytes:
    """The request body, refused with 413 past ``max_bytes`` (before reading it when declared). A
    client that leaves meanwhile raises Starlette's ``ClientDisconnect`` (answered quietly)."""
    check_declared_size(request, max_bytes)
    chunks: list[bytes] = []
    size = 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > max_bytes:
            raise ApiError(413, f"the body is over the {max_bytes} byte limit", "too_large")
        chunks.append(chunk)
    return b"".join(chunks)


def measure_query(request: Request) -> dict[str, Any]:
    """``mode`` and any ``--set`` name (case-insensitive) from the query string."""
    out: dict[str, Any] = {}
    for key, value in request.query_params.multi_items():
        try:
            out.update(field_names({key: value}, option="query parameter"))
        except ValueError as exc:
            raise ApiError(422, str(exc), "invalid_parameters") from None
    return out


@router.post(
    "/measure",
    dependencies=[Depends(require_token)],
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {t: {"schema": {"type": "string", "format": "binary"}} for t in IMAGE_TYPES},
        },
        "parameters": [
            {
                "name": "mode",
                "in": "query",
                "required": False,
                "schema": {"type": "string", "enum": ["precise", "paper"]},
            }
        ],
    },
    responses=problems(
        401,
        403,
        413,
        415,
        s422="an undecodable image, one over the pixel or decoded-size cap, or a bad parameter",
        s503="every measuring slot is taken and the queue is full (busy): try again after Retry-After",
    ),
)
async def measure(request: Request, measurements: Measures) -> dict[str, Any]:
    """The same object as ``station measure --json`` (``ok`` true or false): the image is the raw body.
    At most one image per core is decoded at a time (the largest take every core's turn), a few more
    wait, and the rest get 503 (busy): ``api/_gate.py``."""
    require_type(request, IMAGE_TYPES)
    params = measure_query(request)
    check_declared_size(request, MAX_UPLOAD_BYTES)
    gate: DecodeGate = request.app.state.measure_gate
    limits = ImageLimits(
        max_bytes=MAX_UPLOAD_BYTES, max_decoded_bytes=request.app.state.limits.max_decoded_bytes
    )
    async with gate.place():  # before the body is read: the rest get 503 without sending it
        data = await read_body(request, MAX_UPLOAD_BYTES)
        async with gate.slots_for(gate.weight(_decoded_bytes(data), limits.max_decoded_bytes)):
            return await run_in_threadpool(measurements.measure_image, data, params, limits=limits)


def _decoded_bytes(data: bytes) -> int | None:
    """What the image's header declares it decodes to; None when it has no header this door reads (the
    decoding then refuses it, at once)."""
    try:
        return read_header(data).decoded_bytes
    except (ValueError, struct.error):
        return None
