"""Dependency wiring: the service lives on ``app.state``, never in a module global; ids in paths are
checked against their pattern before anything looks them up."""

from __future__ import annotations

import re
from typing import Annotated

from fastapi import Depends, Path, Request

from api._errors import ApiError
from api._measurements import Measurements
from api._reads import SessionReads
from api._scale_calibrations import ScaleCalibrations
from api._service import StationService
from api._session_files import SessionFiles

SESSION_ID = r"^[0-9A-Fa-f]{4,12}$"
"""A session id (12 hexadecimal digits) or a unique prefix of at least 4 of them."""
PROMPT_ID = r"^[0-9A-Za-z_-]{1,64}$"


def service_of(request: Request) -> StationService:
    service: StationService = request.app.state.service
    return service


def _reads(request: Request) -> SessionReads:
    return service_of(request).reads


def _session_files(request: Request) -> SessionFiles:
    return service_of(request).files


def _measurements(request: Request) -> Measurements:
    return service_of(request).measurements


def _scale_calibrations(request: Request) -> ScaleCalibrations:
    return service_of(request).scale_calibrations


Service = Annotated[StationService, Depends(service_of)]
"""Sessions started and controlled, the arm outside sessions, the operator's prompts: ``api._service``."""
Reads = Annotated[SessionReads, Depends(_reads)]
"""The sessions, the station and the events as clients read them: ``api._reads``."""
Files = Annotated[SessionFiles, Depends(_session_files)]
"""The record's session files (outcome, report, export, import): ``api._session_files``."""
Measures = Annotated[Measurements, Depends(_measurements)]
"""Uploads, camera frames and stored captures measured: ``api._measurements``."""
ScaleCalibrationsDep = Annotated[ScaleCalibrations, Depends(_scale_calibrations)]
"""The station's scale calibration, its history and the revert: ``api._scale_calibrations``."""


async def _session_id(
    session_id: Annotated[
        str,
        Path(
            description="the session's id (12 hexadecimal digits) or a unique prefix of at least 4",
            json_schema_extra={"pattern": SESSION_ID},
        ),
    ],
) -> str:
    if not re.fullmatch(SESSION_ID, session_id):
        raise ApiError(
            404,
            f"no session {session_id!r}: a session id is 12 hexadecimal digits (or a prefix of at least 4); "
            "GET /api/v1/sessions lists them",
            "session_not_found",
        )
    return session_id.lower()


async def _prompt_id(
    prompt_id: Annotated[
        str,
        Path(
            description="the prompt's id, as GET /api/v1/prompt gives it",
            json_schema_extra={"pattern": PROMPT_ID},
        ),
    ],
) -> str:
    if not re.fullmatch(PROMPT_ID, prompt_id):
        raise ApiError(
            404, f"no prompt {prompt_id!r}: GET /api/v1/prompt gives the open one", "prompt_not_found"
        )
    return prompt_id


SessionId = Annotated[str, Depends(_session_id)]
"""A route's ``{session_id}``: 404 unless it has the pattern of a session id (lower-cased)."""
PromptId = Annotated[str, Depends(_prompt_id)]
"""A route's ``{prompt_id}``: 404 unless it has the pattern of a prompt id."""
