"""``/api/v1/prompt``: the open operator prompt; confirm (with the readings set) or cancel it by id."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import Response

from api._auth import read_access, require_token
from api._deps import PromptId, service_of
from api._models import AnswerModel, CancelRequest, ConfirmRequest, PromptModel
from api._openapi import problems

router = APIRouter(prefix="/api/v1/prompt")

ANSWERED_BY = "api"


@router.get(
    "",
    response_model=PromptModel,
    dependencies=[Depends(read_access)],
    responses={204: {"description": "no prompt is open"}, **problems(401, 403)},
)
async def current(request: Request) -> PromptModel | Response:
    prompt = service_of(request).prompt()
    if prompt is None:
        return Response(status_code=204)
    return PromptModel.of(prompt)


ANSWER_PROBLEMS = problems(
    401, 403, 404, 503, s409="the prompt is no longer open", s422="readings the table refuses, or a bad body"
)


@router.post(
    "/{prompt_id}/confirm",
    response_model=AnswerModel,
    dependencies=[Depends(require_token)],
    responses=ANSWER_PROBLEMS,
)
async def confirm(request: Request, prompt_id: PromptId, body: ConfirmRequest | None = None) -> AnswerModel:
    """Confirm; ``readings`` in the prompt's own names and units (e.g. ``{"x_in": 0.5102, "y_in": 0.5}``).
    409 when the prompt is no longer open, 422 for readings the table refuses."""
    readings = body.readings if body is not None else None
    answer = await run_in_threadpool(service_of(request).confirm, prompt_id, readings, by=ANSWERED_BY)
    return AnswerModel.of(answer)


@router.post(
    "/{prompt_id}/cancel",
    response_model=AnswerModel,
    dependencies=[Depends(require_token)],
    responses=ANSWER_PROBLEMS,
)
async def cancel(request: Request, prompt_id: PromptId, body: CancelRequest | None = None) -> AnswerModel:
    reason = body.reason if body is not None else ""
    answer = await run_in_threadpool(
        service_of(request).cancel,
        prompt_id,
        reason=reason or "cancelled in the operator page",
        by=ANSWERED_BY,
    )
    return AnswerModel.of(answer)
