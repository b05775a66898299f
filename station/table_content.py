"""What lies on the X-Y table (issue 23): a session asks the operator to put there what its plan needs.

A plan declares what must lie on the X-Y table for it with an optional ``table_content(params)``: the
artifact's cross (``"cross"``), a ruler (``"ruler"``), the camera-calibration target (``"target"``) or
nothing in particular (``None``). Before the pre-flight (whose scale check grabs a frame before any
motion), when the station's last confirmed content differs or is unknown, the session asks the operator
through the station's prompt broker (kind :data:`PROMPT_KIND`, shown by every front end: the API's
``/api/v1/prompt`` and the page's prompt panel, the terminal of ``station run``, the simulated operator)
to put it there and confirm. A declined prompt ends the session as a declined micrometer prompt does
(:class:`~station.devices.OperatorCancelledError`, with what to do); nobody answering within the plan's
``prompt_timeout_s`` withdraws it (:class:`~station.devices.DeviceTimeoutError`).

Where it is remembered: the record. Every session that needed something on the table carries a
:data:`EVENT` event ``{content, asked, by, opened}``; ``opened`` names this opening of the station's
devices (``StationDevices.opened_id``). The station's last confirmed content is that of the newest such
event of the same opening: a station restarted (devices opened anew: the table may have been changed
meanwhile) knows nothing and asks again; a later session of the same opening needing the same content
does not ask.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, Literal, get_args

from station.devices import DeviceError, DeviceTimeoutError, OperatorCancelledError
from station.prompts import Outcome, PromptBusyError
from station.record import Record, RecordError

__all__ = [
    "EVENT",
    "LABELS",
    "PROMPT_KIND",
    "TABLE_CONTENTS",
    "TableContent",
    "needed_content",
    "place_for_session",
    "prompt_message",
    "remembered",
]

log = logging.getLogger(__name__)

TableContent = Literal["cross", "ruler", "target"]
TABLE_CONTENTS: tuple[TableContent, ...] = get_args(TableContent)
PROMPT_KIND = "table_content"
"""The prompt's ``kind``; its ``details`` carry ``content`` (what to put there) and ``was`` (what the
station last knew to lie there, ``unknown`` when nothing)."""
EVENT = "table_content"
"""The session event recording what lay on the table for it."""
LABELS: dict[TableContent, str] = {
    "cross": "artifact's cross",
    "ruler": "ruler",
    "target": "ChArUco calibration target",
}
_WHERE: dict[TableContent, str] = {
    "cross": "the crossed-groove artifact, its crossing under the camera at the reference pose",
    "ruler": "in the artifact's place, graduations up, its middle under the camera at the reference pose "
    "and along the artifact's horizontal groove",
    "target": "in the artifact's place, printed side up, its centre under the camera at the reference pose "
    "and its edges along the table's axes",
}


def needed_content(plan: Any, params: Any) -> TableContent | None:
    """What ``plan`` needs on the X-Y table with ``params`` (its optional ``table_content``), or None."""
    declare: Callable[[Any], Any] | None = getattr(plan, "table_content", None)
    content = None if declare is None else declare(params)
    if content is not None and content not in TABLE_CONTENTS:
        raise ValueError(f"plan {plan.name!r} asks for {content!r} on the table; one of {TABLE_CONTENTS}")
    return content


def prompt_message(content: TableContent) -> str:
    """What the operator is asked (``Put the <label> on the X-Y table ... then confirm``)."""
    return (
        f"Put the {LABELS[content]} on the X-Y table ({_WHERE[content]}), then confirm; "
        "cancel if you cannot: the session then ends before anything moves"
    )


def remembered(record: Record, opened_id: str) -> tuple[TableContent | None, str | None]:
    """The station's last confirmed table content for this opening of its devices, and the session that
    recorded it; ``(None, None)`` when unknown (nothing confirmed since the devices were opened)."""
    try:
        last = record.last_event(EVENT)
    except RecordError as exc:  # the record cannot say: ask
        log.warning("the last table content could not be read from the record (%s): asking", exc)
        return None, None
    if last is None:
        return None, None
    data = last.data
    if data.get("opened") != opened_id or data.get("content") not in TABLE_CONTENTS:
        return None, None  # confirmed before a restart: the table may have changed since
    content: TableContent = data["content"]
    return content, last.session_id


def place_for_session(
    plan: Any,
    params: Any,
    devices: Any,
    record: Record,
    emit: Callable[[str, dict[str, Any]], None],
    *,
    before_asking: Callable[[], None] | None = None,
) -> TableContent | None:
    """Make sure what ``plan`` needs lies on the X-Y table of ``devices`` (a ``StationDevices``): ask the
    operator unless the station's last confirmed content is that; record it (:data:`EVENT`) either way.

    Returns the content (None: the plan needs nothing in particular, nothing asked or recorded). Raises
    ``OperatorCancelledError`` when the operator declines, ``DeviceTimeoutError`` when nobody answers
    within the plan's ``prompt_timeout_s``, ``DeviceError`` when another prompt is open, and what
    ``before_asking`` raises (called only when the operator is to be asked: the runner's checks that need
    no frame, so that a session that cannot run asks nobody for anything).
    """
    needed = needed_content(plan, params)
    if needed is None or devices is None:
        return None
    opened: str = devices.opened_id
    known, where = remembered(record, opened)
    if known == needed:
        log.info("the %s is on the X-Y table (confirmed in session %s)", LABELS[needed], where)
        emit(EVENT, {"content": needed, "asked": False, "by": "", "confirmed_in": where, "opened": opened})
        return needed
    if before_asking is not None:
        before_asking()
    timeout_s = getattr(params, "prompt_timeout_s", None)
    try:
        handle = devices.broker.ask(
            prompt_message(needed),
            kind=PROMPT_KIND,
            source="table",
            details={"content": needed, "label": LABELS[needed], "was": known or "unknown"},
        )
    except PromptBusyError as exc:
        raise DeviceError(f"cannot ask for the {LABELS[needed]} on the X-Y table: {exc}") from exc
    try:
        answer = handle.wait(timeout_s)
    except TimeoutError:
        answer = handle.withdraw(reason=f"no answer within {timeout_s} s")
    again = f"put the {LABELS[needed]} on the X-Y table, then start the session again (it asks again)"
    if answer.outcome is Outcome.WITHDRAWN:
        raise DeviceTimeoutError(
            f"nobody confirmed the {LABELS[needed]} on the X-Y table within {timeout_s} s; nothing moved: "
            + again
        )
    if answer.outcome is Outcome.CANCELLED:
        reason = f" ({answer.reason})" if answer.reason else ""
        raise OperatorCancelledError(
            f"the operator declined to put the {LABELS[needed]} on the X-Y table{reason}; nothing moved: "
            + again
        )
    emit(EVENT, {"content": needed, "asked": True, "by": answer.by, "confirmed_in": None, "opened": opened})
    return needed
