"""An archive selection: the stored sessions an offline plan (``reanalyse``, ``sweep``) reads, named one
by one (``sessions=["id1", "id2"]``) or by a filter (``select={"kind": ..., "station": ..., "since":
"2026-01-01"}``), beside the single ``session`` of one stored session.

Every session of a selection is checked before any task is sent: it exists, its kind fits the plan, it
has the captures the plan needs and their images are in the data directory. One ``PlanError`` lists every
session that fails, each with what to do.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC, date, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    model_serializer,
    model_validator,
)

from station.plans import PlanError

if TYPE_CHECKING:
    from station.record import CaptureRow, Record, SessionRow

#: A filter selects the sessions that completed: a failed or interrupted one is named by id if wanted.
SELECTED_STATE = "succeeded"
#: The plan parameters that name what an offline plan reads: exactly one is given.
SOURCE_FORMS = ("session", "sessions", "select")
#: Images listed per session in an error (the count is always given).
SHOWN_MISSING = 3


class SessionFilter(BaseModel):
    """``select={...}``: the record's succeeded sessions of a kind, a station, created since a day (UTC),
    oldest first; every key is optional."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    kind: str | None = Field(None, min_length=1, description="session kind, e.g. 'validation'")
    station: str | None = Field(None, min_length=1, description="station name, as the sessions recorded it")
    since: date | None = Field(None, description="first day (UTC, ISO 8601: '2026-01-01') of the sessions")

    def text(self) -> str:
        """The filter as given, for messages."""
        return "select=" + self.model_dump_json(exclude_none=True)


@dataclass(frozen=True)
class Source:
    """One session of a selection, checked: its row and the captures the plan reads (in order)."""

    session: SessionRow
    captures: tuple[CaptureRow, ...]


#: A plan's view of a stored session: the captures it reads, or the reason it cannot (what to do in it).
Reader = Callable[["SessionRow", "Record"], "tuple[CaptureRow, ...] | str"]


def without_unused(doc: dict[str, Any]) -> dict[str, Any]:
    """A plan's parameters as stored, without the source forms not given: a session of one stored
    session records its parameters as it always did."""
    return {k: v for k, v in doc.items() if not (k in SOURCE_FORMS and v is None)}


def selection_problem(
    session: str | None, sessions: Sequence[str] | None, select: object | None
) -> str | None:
    """Why a plan's source parameters are not exactly one of ``session``, ``sessions``, ``select`` (None:
    they are)."""
    given = [
        n for n, v in (("session", session), ("sessions", sessions), ("select", select)) if v is not None
    ]
    if len(given) != 1:
        said = " and ".join(given) if given else "none of them"
        return f"give exactly one of session, sessions or select (got {said})"
    if sessions is not None:
        if not sessions:
            return 'sessions is empty: name at least one stored session, e.g. sessions=["3f2a91c04b7e"]'
        seen: set[str] = set()
        for s in sessions:
            key = s.strip().lower()
            if key in seen:
                return f"sessions names {s!r} twice: name each session once"
            seen.add(key)
    return None


class SourceParams(BaseModel):
    """The source parameters of a plan that reads stored sessions (reanalyse, sweep): exactly one of
    ``session``, ``sessions`` and ``select``, stored without the forms not given."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    session: str | None = Field(None, min_length=4, description="id (or unique prefix) of a stored session")
    sessions: list[str] | None = Field(
        None, description="an archive selection by ids (or unique prefixes) of stored sessions"
    )
    select: SessionFilter | None = Field(
        None, description="an archive selection by filter: the succeeded sessions of kind, station, since"
    )

    @model_serializer(mode="wrap")
    def _stored(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        return without_unused(handler(self))

    @model_validator(mode="after")
    def _one_source(self) -> SourceParams:
        problem = selection_problem(self.session, self.sessions, self.select)
        if problem is not None:
            raise ValueError(problem)
        return self


def resolve(
    record: Record,
    *,
    session: str | None,
    sessions: Sequence[str] | None,
    select: SessionFilter | None,
    fits: Callable[[str], str | None],
    read: Reader,
    created_before: datetime | None = None,
) -> list[Source]:
    """The selection's sessions, each checked; PlanError listing every one that fails.

    ``fits(kind)``: why the plan cannot read a session of this kind (None: it can); ``read``: the captures
    of a session the plan reads, or why they cannot be read. A filter without ``kind`` takes the sessions
    whose kind fits; ``created_before`` (the session that reads them) keeps a resumed run's selection the
    one it started with.
    """
    problem = selection_problem(session, sessions, select)
    if problem is not None:
        raise PlanError(problem)
    bad: list[str] = []
    if select is not None:
        rows = _filtered(record, select, fits, created_before)
    else:
        rows, bad = _named(record, [session] if session is not None else list(sessions or ()))
    total = len(rows) + len(bad)
    out: list[Source] = []
    for row in rows:
        reason = fits(row.kind)
        got = read(row, record) if reason is None else reason
        if isinstance(got, str):
            bad.append(f"session {row.id} ({row.kind}): {got}")
        else:
            out.append(Source(row, got))
    if bad:
        raise PlanError(_listing(bad, total))
    return out


def missing_images(record: Record, captures: Sequence[CaptureRow]) -> str | None:
    """Why some of these captures' images cannot be read (None: every one is a file of the data
    directory)."""
    root = Path(record.data_dir)
    missing = [c.path for c in captures if not (root / c.path).is_file()]
    if not missing:
        return None
    shown = ", ".join(missing[:SHOWN_MISSING]) + (" ..." if len(missing) > SHOWN_MISSING else "")
    return (
        f"{len(missing)} of its {len(captures)} images are missing from {root} ({shown}): restore them "
        "from the lab's backup, or import the session again (station sessions import DIR|ZIP)"
    )


def _named(record: Record, ids: Sequence[str]) -> tuple[list[SessionRow], list[str]]:
    from station.record import RecordError

    rows: list[SessionRow] = []
    bad: list[str] = []
    for sid in ids:
        try:
            rows.append(record.get_session(sid))
        except RecordError as exc:
            bad.append(f"session {sid!r}: {exc}")  # says how to list the record's sessions
    return rows, bad


def _filtered(
    record: Record,
    select: SessionFilter,
    fits: Callable[[str], str | None],
    created_before: datetime | None,
) -> list[SessionRow]:
    if select.kind is not None and (reason := fits(select.kind)) is not None:
        raise PlanError(f"{select.text()}: {reason}")
    since = None if select.since is None else datetime(*select.since.timetuple()[:3], tzinfo=UTC)
    rows = [
        r
        for r in record.list_sessions(select.kind)
        if r.state == SELECTED_STATE
        and (select.station is None or r.station == select.station)
        and (since is None or r.created_at >= since)
        and (created_before is None or r.created_at < created_before)
        and (select.kind is not None or fits(r.kind) is None)
    ]
    if not rows:
        raise PlanError(
            f"{select.text()} matches no {SELECTED_STATE} session in the record at {record.url}: widen the "
            "filter, or list the sessions with: station sessions"
        )
    rows.sort(key=lambda r: (r.created_at, r.id))  # oldest first: a resumed run plans the same steps
    return rows


def _listing(bad: Sequence[str], total: int) -> str:
    head = f"{len(bad)} of the {total} selected sessions cannot be read; nothing was measured:"
    return "\n".join([head, *(f"  - {b}" for b in bad)])
