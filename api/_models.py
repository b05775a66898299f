"""The API's bodies: pydantic models, the same objects the CLI prints with ``--json``.

The session objects are ``station.resources``' models, which the CLI renders too (one model, two
renderings): :class:`~station.resources.SessionResource` (``station sessions --json``'s object plus the
live progress) and :class:`~station.resources.SessionOutcome` (``station run --json``'s object). The
routes document them as ``SessionModel`` and ``OutcomeModel``: the same objects typed per kind (a union
discriminated on ``kind``, ``results`` that kind's results model), so that the OpenAPI document shows
each kind's results. The rest are the API's own (requests, prompts, events, problems).
"""

from __future__ import annotations

from typing import Any, Literal

from fastapi.responses import Response
from pydantic import BaseModel, ConfigDict, Field

from api._service import SessionView
from station.kinds import KIND_NAMES
from station.prompts import Prompt, PromptAnswer
from station.record import EventRow
from station.resources import SessionResource, TypedSessionOutcome, TypedSessionResource


class Problem(BaseModel):
    """RFC 9457 problem details; ``code`` is the stable name of the refusal."""

    type: str
    title: str
    status: int
    detail: str
    code: str
    problems: list[str] | None = Field(None, description="pre-flight's findings (code preflight_failed)")


class Health(BaseModel):
    status: Literal["ok"] = "ok"
    version: str


class AccessModel(BaseModel):
    """What the client may do: ``authenticated`` (it sent the station's token, or the login cookie) and
    ``open_reads`` (reads need no token), ``local`` (it runs on the station itself)."""

    authenticated: bool
    open_reads: bool
    local: bool = Field(
        description="whether the request comes from the station itself (a loopback peer): only such a"
        " client may acknowledge a latched stop"
    )
    motion: bool = Field(
        description="whether this client may start or resume sessions that drive the devices and move the"
        " arm: ``local``, or any client when the service runs with --allow-remote-motion"
    )


class PlanModel(BaseModel):
    """A session kind: its name, the devices it drives, and its parameters' JSON schema (every
    parameter's default shown, including those computed when a session is created)."""

    name: str
    needs: list[str]
    params_schema: dict[str, Any]


class PlanList(BaseModel):
    plans: list[PlanModel]


SessionModel = TypedSessionResource
OutcomeModel = TypedSessionOutcome


def session_model(view: SessionView) -> SessionResource:
    """The resource of a session the service shows (its row and live progress)."""
    return SessionResource.of_row(view.row, view.progress)


def rendered(model: BaseModel, status_code: int = 200) -> Response:
    """``model`` as the response body, rendered once by pydantic (the route's ``response_model`` still
    documents it): FastAPI would dump the model, validate the dump and serialize it again, on every poll.
    For models the service builds from checked data (the record's rows, the runner's progress)."""
    return Response(model.model_dump_json(), status_code=status_code, media_type="application/json")


class SessionList(BaseModel):
    """A page of sessions (documented: each typed by its kind)."""

    items: list[SessionModel]  # type: ignore[valid-type]
    total: int


class SessionPage(BaseModel):
    """What renders :class:`SessionList` (the resources as recorded)."""

    items: list[SessionResource]
    total: int


class SessionCreate(BaseModel):
    """``{"kind": ..., "params": {...}, "set": {...}}``: a plan and its parameters (``--param``), and
    measurement parameters (``--set``)."""

    model_config = ConfigDict(extra="forbid")

    kind: str = Field(description="the session's plan", json_schema_extra={"enum": list(KIND_NAMES)})
    params: dict[str, Any] = Field(default_factory=dict, description="the plan's parameters")
    set: dict[str, Any] = Field(default_factory=dict, description="measurement parameters, as --set")


class ActionRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    action: Literal["pause", "resume", "stop", "abort"]


class PromptFieldModel(BaseModel):
    name: str
    label: str
    unit: str
    requested: float | None


class PromptModel(BaseModel):
    id: str
    kind: str
    message: str
    fields: list[PromptFieldModel]
    source: str
    created_s: float
    details: dict[str, str | float]

    @classmethod
    def of(cls, p: Prompt) -> PromptModel:
        return cls(
            id=p.id,
            kind=p.kind,
            message=p.message,
            fields=[PromptFieldModel(**f.__dict__) for f in p.fields],
            source=p.source,
            created_s=p.created_s,
            details=dict(p.details),
        )


class ConfirmRequest(BaseModel):
    """The readings actually set, in the prompt's own field names and units (e.g. ``x_in``)."""

    model_config = ConfigDict(extra="forbid")

    readings: dict[str, float] | None = None


class CancelRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    reason: str = Field("", max_length=500)


class AnswerModel(BaseModel):
    prompt_id: str
    outcome: str
    readings: dict[str, float]
    by: str
    reason: str

    @classmethod
    def of(cls, a: PromptAnswer) -> AnswerModel:
        return cls(
            prompt_id=a.prompt.id, outcome=str(a.outcome), readings=dict(a.readings), by=a.by, reason=a.reason
        )


class EventModel(BaseModel):
    id: int
    session_id: str
    seq: int
    time: str
    type: str
    data: dict[str, Any]

    @classmethod
    def of(cls, e: EventRow) -> EventModel:
        return cls(
            id=e.id, session_id=e.session_id, seq=e.seq, time=e.time.isoformat(), type=e.type, data=e.data
        )


class StationModel(BaseModel):
    name: str
    sim: bool
    manual_prompts: bool
    config: dict[str, Any] | None
    devices: dict[str, Any]
    data_dir: str
    record: str
    session: dict[str, Any] | None
    lock: dict[str, Any] | None
    plans: list[str]
    worker: dict[str, Any] | None = None
    """The station's worker process (``alive``, ``pid``, ``nice``): it owns the devices and runs the
    sessions."""
    robot: dict[str, Any] | None = None
    """The robot's state and pose, read between sessions (``state``: ``reading``, ``idle``,
    ``in_session`` or ``unreachable``; ``power``, ``homed``, ``joints_deg``, ``commanded_joints_deg``,
    ``reference_joints_deg``, ``at_reference``, ``read_at``, ``error``); None without a robot."""
    selftest: dict[str, Any] | None = None
    """The latest controller self-test of this robot (``station run selftest``): ``session_id``, ``passed``,
    ``when``; None without a robot or before its first self-test (``station.selftest_status``)."""
