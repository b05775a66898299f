"""Server-Sent Events: ``/api/v1/sessions/{id}/events`` (``id:`` the session's sequence number) and
``/api/v1/events`` (``id:`` the station-wide event id), resuming after ``Last-Event-ID``.

The record is the source: a stream sends what the record holds after the client's last id, then waits
for the runner's next event (woken at once in this process, and polling the record every second for
sessions run by another process). A session's stream reads the running session's events from the
service's in-memory buffer (the record only for older ones), and all the streams of the app share one
subscription to the runner's events (:class:`_Hub`): the runner's thread pays for one wake-up of the
event loop per burst of events, not one per client, and each event is rendered once.

HTTP stays the source of truth: an event is a hint to refetch, and a client that missed some gets them
again from the record. A session's stream ends once the session has
ended and everything is sent; the station's stream runs until the client leaves or the server stops.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Header, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.sse import EventSourceResponse, ServerSentEvent

from api._auth import stream_access
from api._deps import Reads, SessionId, service_of
from api._models import EventModel
from api._openapi import problems
from station.record import EventRow, RecordUnavailableError
from station.runner import FINAL_STATES

log = logging.getLogger(__name__)

router = APIRouter(prefix="/api/v1")

POLL_S = 1.0
RETRY_MS = 2000


LastEventId = Annotated[
    int | None,
    Header(
        alias="Last-Event-ID",
        ge=0,
        le=10**18,
        description="resume after this event id (a browser's EventSource sends it when it reconnects)",
    ),
]


RENDERED = 4096
"""Events kept rendered (their ``data:`` JSON) for the streams that send them next."""


class _Hub:
    """The app's one subscription to the service's events, on the event loop ``loop``.

    The thread that reads the station worker's reports calls :meth:`_on_event`: it schedules one wake-up
    of the loop unless one is pending already (a write to the loop's self-pipe: one per burst, not one
    per client), and the loop then wakes every stream.
    """

    def __init__(self, request: Request, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self._waiters: set[asyncio.Event] = set()
        self._pending = False
        self._rendered: dict[int, str] = {}
        self._unsubscribe = service_of(request).reads.subscribe(self._on_event)

    def _on_event(self, _: EventRow) -> None:
        if self._pending:
            return
        self._pending = True
        try:
            self.loop.call_soon_threadsafe(self._wake)
        except RuntimeError:  # the loop has closed (the server stopped)
            self._unsubscribe()

    def _wake(self) -> None:
        self._pending = False
        for waiter in self._waiters:
            waiter.set()

    def waiter(self) -> asyncio.Event:
        w = asyncio.Event()
        self._waiters.add(w)
        return w

    def release(self, waiter: asyncio.Event) -> None:
        self._waiters.discard(waiter)

    def render(self, e: EventRow) -> str:
        """The event's ``data:`` JSON, rendered once for every stream."""
        text = self._rendered.get(e.id)
        if text is None:
            text = EventModel.of(e).model_dump_json()
            if len(self._rendered) >= RENDERED:
                self._rendered.pop(next(iter(self._rendered)))
            self._rendered[e.id] = text
        return text


def _hub(request: Request) -> _Hub:
    loop = asyncio.get_running_loop()
    state: Any = request.app.state
    hub: _Hub | None = getattr(state, "event_hub", None)
    if hub is None or hub.loop is not loop:
        hub = state.event_hub = _Hub(request, loop)
    return hub


async def _wait(waiter: asyncio.Event, timeout_s: float) -> None:
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(waiter.wait(), timeout_s)


async def session_cursor(
    reads: Reads, session_id: SessionId, last_event_id: LastEventId = None
) -> tuple[str, int]:
    """The session's full id and the sequence number to resume after: checked before the stream starts
    (404 for an unknown session, 422 for a malformed Last-Event-ID). Coroutines, like the token check
    (see ``api/_auth.py``): this process's running session needs no look-up."""
    after = last_event_id or 0
    if reads.session_ended(session_id) is not None:  # this process's latest session, by its full id
        return session_id, after
    return await run_in_threadpool(reads.session_id, session_id), after


async def station_cursor(last_event_id: LastEventId = None) -> int:
    return last_event_id or 0


STREAM = {
    "description": "the events, as Server-Sent Events",
    "content": {"text/event-stream": {"schema": {"type": "string"}}},
}


def _sse(hub: _Hub, e: EventRow, event_id: int) -> ServerSentEvent:
    return ServerSentEvent(raw_data=hub.render(e), event=e.type, id=str(event_id))


@router.get(
    "/sessions/{session_id}/events",
    response_class=EventSourceResponse,
    dependencies=[Depends(stream_access)],
    responses={200: STREAM, **problems(401, 403, 404, 422, 503)},
)
async def session_events(
    request: Request, reads: Reads, cursor: tuple[str, int] = Depends(session_cursor)
) -> AsyncIterator[ServerSentEvent]:
    """The session's events from after ``Last-Event-ID`` (its sequence number), live until it ends."""
    sid, after_seq = cursor
    hub = _hub(request)
    waiter = hub.waiter()
    try:
        yield ServerSentEvent(comment="station session events", retry=RETRY_MS)
        last_seq = after_seq
        while True:
            waiter.clear()  # before reading: an event recorded after the read wakes the wait below
            # the running session's events from memory, on the loop; the record (a thread) otherwise
            batch = reads.buffered_events(sid, last_seq)
            if batch is None:
                batch = await run_in_threadpool(reads.events_after_seq, sid, last_seq)
            for e in batch:
                yield _sse(hub, e, e.seq)
                last_seq = e.seq
            if not batch:
                ended = reads.session_ended(sid)
                if ended is None:  # not this process's session: ask the record
                    ended = (await run_in_threadpool(reads.session_state, sid)) in FINAL_STATES
                if ended:
                    # a last look: events recorded between the read and the state
                    for e in await run_in_threadpool(reads.events_after_seq, sid, last_seq):
                        yield _sse(hub, e, e.seq)
                    return
                if request.app.state.stopping.is_set() or await request.is_disconnected():
                    return
                await _wait(waiter, POLL_S)
    except RecordUnavailableError as exc:
        _record_gone(sid, exc)
    finally:
        hub.release(waiter)


def _record_gone(what: str, exc: RecordUnavailableError) -> None:
    """The record went away under a stream: it ends (one log line); the client's reconnection is
    answered 503 ``record_unavailable`` until the record is back, and resumes from Last-Event-ID."""
    log.warning("event stream of %s ended: %s", what, exc)


@router.get(
    "/events",
    response_class=EventSourceResponse,
    dependencies=[Depends(stream_access)],
    responses={200: STREAM, **problems(401, 403, 422, 503)},
)
async def station_events(
    request: Request, reads: Reads, after_id: int = Depends(station_cursor)
) -> AsyncIterator[ServerSentEvent]:
    """Every session's events from after ``Last-Event-ID`` (the station-wide id), until the client leaves."""
    hub = _hub(request)
    waiter = hub.waiter()
    try:
        yield ServerSentEvent(comment="station events", retry=RETRY_MS)
        while True:
            waiter.clear()
            batch = await run_in_threadpool(reads.events, None, after_id=after_id)
            for e in batch:
                yield _sse(hub, e, e.id)
                after_id = e.id
            if not batch:
                if request.app.state.stopping.is_set() or await request.is_disconnected():
                    return
                await _wait(waiter, POLL_S)
    except RecordUnavailableError as exc:
        _record_gone("the station", exc)
    finally:
        hub.release(waiter)
