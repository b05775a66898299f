"""``/api/v1/plans``: the session kinds and their parameters as JSON schema (the page's start form)."""

from __future__ import annotations

import functools
from typing import Any

from fastapi import APIRouter, Depends
from pydantic_core import to_jsonable_python

from api._auth import read_access
from api._models import PlanList, PlanModel
from api._openapi import problems
from station.kinds import KIND_NAMES, get_plan

router = APIRouter(prefix="/api/v1")


def plan_schema(name: str) -> dict[str, Any]:
    """The plan's parameter model as JSON schema, with the default of every optional parameter (pydantic
    leaves out those a factory computes, such as repeatability's ``joints``)."""
    model = get_plan(name).Params
    schema = model.model_json_schema()
    properties = schema.get("properties", {})
    for field_name, info in model.model_fields.items():
        prop = properties.get(info.alias or field_name)
        if prop is not None and "default" not in prop and not info.is_required():
            prop["default"] = to_jsonable_python(info.get_default(call_default_factory=True))
    return schema


@functools.cache
def plan_list() -> PlanList:
    """Every plan with its schema: a constant of the code, computed once."""
    return PlanList(
        plans=[
            PlanModel(name=n, needs=sorted(get_plan(n).needs), params_schema=plan_schema(n))
            for n in KIND_NAMES
        ]
    )


@router.get(
    "/plans", response_model=PlanList, dependencies=[Depends(read_access)], responses=problems(401, 403)
)
async def plans() -> PlanList:
    """Every session kind the station runs (``/station``'s ``plans``), with its parameters' schema."""
    return plan_list()
