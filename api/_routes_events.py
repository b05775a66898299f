"""Server-Sent Events: ``/api/v1/sessions/{id}/events`` (``id:`` the session's sequence number) and
``/api/v1/events`` (``id:`` the station-wide event id), resuming after ``Last-Event-ID``.

The record is the source: a stream sends what the record holds after the client's last id, then waits
for the runner's next event (woken at once in this process, and polling the record every second for
sessions run by another process). HTTP stays the source of truth: an event is a hint to refetch, and a
client that missed some gets them again from the record. A session's stream ends once the session has
ended and everything is sent; the station's stream runs until the client leaves or the server stops.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator

from fastapi import APIRouter, Depends, Header, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.sse import EventSourceResponse, ServerSentEvent

from api._auth import require_token
from api._deps import service_of
from api._errors import ApiError
from api._models import EventModel
from station.record import EventRow
from station.runner import FINAL_STATES

router = APIRouter(prefix="/api/v1")

POLL_S = 1.0
RETRY_MS = 2000


def _last_id(value: str | None) -> int:
    if value is None or not value.strip():
        return 0
    text = value.strip()
    if not text.isdigit() or len(text) > 18:
        raise ApiError(422, f"Last-Event-ID must be a non-negative integer, got {value!r}", "invalid_request")
    return int(text)


class _Wakeup:
    """Set from the runner's thread when an event is recorded; the stream then reads the record."""

    def __init__(self, request: Request) -> None:
        self._loop = asyncio.get_running_loop()
        self.event = asyncio.Event()
        self._unsubscribe = service_of(request).subscribe(self._on_event)

    def _on_event(self, _: EventRow) -> None:
        self._loop.call_soon_threadsafe(self.event.set)

    async def wait(self, timeout_s: float) -> None:
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self.event.wait(), timeout_s)
        self.event.clear()

    def close(self) -> None:
        self._unsubscribe()


def session_cursor(
    request: Request, session_id: str, last_event_id: str | None = Header(None)
) -> tuple[str, int]:
    """The session's full id and the sequence number to resume after: checked before the stream starts
    (404 for an unknown session, 422 for a malformed Last-Event-ID)."""
    after = _last_id(last_event_id)
    return service_of(request).record.get_session(session_id).id, after


def station_cursor(last_event_id: str | None = Header(None)) -> int:
    return _last_id(last_event_id)


def _sse(e: EventRow, event_id: int) -> ServerSentEvent:
    return ServerSentEvent(data=EventModel.of(e).model_dump(mode="json"), event=e.type, id=str(event_id))


@router.get(
    "/sessions/{session_id}/events",
    response_class=EventSourceResponse,
    dependencies=[Depends(require_token)],
)
async def session_events(
    request: Request, session_id: str, cursor: tuple[str, int] = Depends(session_cursor)
) -> AsyncIterator[ServerSentEvent]:
    """The session's events from after ``Last-Event-ID`` (its sequence number), live until it ends."""
    service = service_of(request)
    sid, after_seq = cursor
    wake = _Wakeup(request)
    try:
        yield ServerSentEvent(comment="station session events", retry=RETRY_MS)
        last_seq = after_seq
        while True:
            batch = await run_in_threadpool(service.events_after_seq, sid, last_seq)
            for e in batch:
                yield _sse(e, e.seq)
                last_seq = e.seq
            if not batch:
                state = (await run_in_threadpool(service.record.get_session, sid)).state
                if state in FINAL_STATES:
                    # a last look: events recorded between the read and the state
                    for e in await run_in_threadpool(service.events_after_seq, sid, last_seq):
                        yield _sse(e, e.seq)
                    return
                if request.app.state.stopping.is_set() or await request.is_disconnected():
                    return
                await wake.wait(POLL_S)
    finally:
        wake.close()


@router.get("/events", response_class=EventSourceResponse, dependencies=[Depends(require_token)])
async def station_events(
    request: Request, after_id: int = Depends(station_cursor)
) -> AsyncIterator[ServerSentEvent]:
    """Every session's events from after ``Last-Event-ID`` (the station-wide id), until the client leaves."""
    service = service_of(request)
    wake = _Wakeup(request)
    try:
        yield ServerSentEvent(comment="station events", retry=RETRY_MS)
        while True:
            batch = await run_in_threadpool(service.record.events, None, after_id=after_id)
            for e in batch:
                yield _sse(e, e.id)
                after_id = e.id
            if not batch:
                if request.app.state.stopping.is_set() or await request.is_disconnected():
                    return
                await wake.wait(POLL_S)
    finally:
        wake.close()
