"""The session objects the station shows: one pydantic model each, rendered by the CLI's ``--json`` and
by the service's API (``api/``) alike.

* :class:`SessionSummary`: a session as ``station sessions --json`` lists it (the record's row without
  its configuration, identities and software);
* :class:`SessionResource`: the API's session resource, the summary plus the live ``progress``
  (``station.runner.Progress``: ``{"done", "total", "eta_s"}``) and ``results`` always an object
  (``{}`` before there are any);
* :class:`SessionOutcome`: ``station run --json``'s object, ``{"id", "kind", "state", "results",
  "error"}``, which is also ``GET /api/v1/sessions/{id}/results``.

``TypedSessionResource`` and ``TypedSessionOutcome`` are the same objects as the API's OpenAPI document
publishes them: a union discriminated on ``kind`` whose ``results`` is that kind's typed results model
(``station.kinds``). They document; they are never used to render (the results are the analysis's own
object, shown as recorded).

The keys are a contract (scripts read them): change them only with the CLI's and the API's docs.
"""

from __future__ import annotations

import json
import re
from typing import Annotated, Any, Literal, TypeVar, Union

from pydantic import BaseModel, ConfigDict, Field, create_model

from station.kinds import KINDS
from station.plans._kind import Kind
from station.record import SessionRow
from station.runner import Progress, SessionState


class SessionSummary(BaseModel):
    """A recorded session: ``station sessions --json``'s object."""

    id: str
    kind: str
    state: SessionState
    created_at: str = Field(description="ISO 8601, UTC")
    updated_at: str = Field(description="ISO 8601, UTC")
    station: str
    parent_id: str | None
    error: str | None
    params: dict[str, Any]
    results: dict[str, Any] | None

    @classmethod
    def fields_of(cls, row: SessionRow) -> dict[str, Any]:
        return {
            "id": row.id,
            "kind": row.kind,
            "state": SessionState(row.state),
            "created_at": row.created_at.isoformat(),
            "updated_at": row.updated_at.isoformat(),
            "station": row.station,
            "parent_id": row.parent_id,
            "error": row.error,
            "params": row.params,
            "results": row.results,
        }

    @classmethod
    def of(cls, row: SessionRow) -> SessionSummary:
        # the row comes from the record (already checked on the way in): built without re-validating the
        # params and results trees, which the service renders on every poll
        return cls.model_construct(**cls.fields_of(row))


class SessionResource(SessionSummary):
    """The API's session resource: the summary, its results always an object, and the live progress."""

    results: dict[str, Any]
    progress: Progress

    @classmethod
    def of_row(cls, row: SessionRow, progress: Progress) -> SessionResource:
        fields = cls.fields_of(row)
        fields["results"] = fields["results"] or {}
        return cls.model_construct(**fields, progress=progress)


class SessionOutcome(BaseModel):
    """How a session ended (or stands): ``station run --json``'s object."""

    id: str
    kind: str
    state: SessionState
    results: dict[str, Any]
    error: str | None = None

    @classmethod
    def of(cls, row: SessionRow) -> SessionOutcome:
        return cls.model_construct(
            id=row.id,
            kind=row.kind,
            state=SessionState(row.state),
            results=row.results or {},
            error=row.error,
        )

    def to_json(self) -> dict[str, Any]:
        """The object as ``json.dumps`` takes it (what ``--json`` prints)."""
        return self.model_dump()


def report_document(row: SessionRow) -> dict[str, Any]:
    """What ``station.reporting.write_report`` takes: the session object (``station sessions --json``'s)
    with its identities and software."""
    return {**SessionSummary.of(row).model_dump(), "identities": row.identities, "software": row.software}


class NoResults(BaseModel):
    """``{}``: the session has no results (yet)."""

    model_config = ConfigDict(extra="forbid", title="NoResults")


M = TypeVar("M", bound=BaseModel)


def _variant(base: type[M], kind: Kind, suffix: str) -> type[M]:
    title = "".join(part.capitalize() for part in re.split(r"[-_]", kind.name)) + suffix
    literal: Any = Literal[kind.name]  # a kind's name, known at run time
    results: Any = kind.results | NoResults
    return create_model(
        title,
        __base__=base,
        __module__=__name__,
        kind=(literal, Field(description="the session's kind")),
        results=(
            results,
            Field(description=f"the {kind.name} analysis's results ({{}} before there are any)"),
        ),
    )


def by_kind(base: type[M], suffix: str) -> Any:
    """``base`` as one model per registered kind (``kind`` a literal, ``results`` that kind's results
    model), discriminated on ``kind``: what the OpenAPI document shows."""
    variants = tuple(_variant(base, k, suffix) for k in KINDS.values())
    return Annotated[Union[variants], Field(discriminator="kind")]  # noqa: UP007 - built at run time


TypedSessionResource = by_kind(SessionResource, "Session")
TypedSessionOutcome = by_kind(SessionOutcome, "Outcome")


def dumps(model: BaseModel | list[Any]) -> str:
    """The CLI's rendering of a model (or a list of them): one line of JSON, as ``json.dumps`` writes it
    (the state enum is a string; a NaN in a result prints as ``NaN``, as it always has)."""
    if isinstance(model, list):
        return json.dumps([m.model_dump() if isinstance(m, BaseModel) else m for m in model])
    return json.dumps(model.model_dump())


__all__ = [
    "NoResults",
    "SessionOutcome",
    "SessionResource",
    "SessionSummary",
    "TypedSessionOutcome",
    "TypedSessionResource",
    "by_kind",
    "dumps",
    "report_document",
]
