"""``/api/v1/station/scale-calibration``: the station's scale calibration, its history, and the revert.

The same objects as ``station scale-calibration show|history|revert --json``. Reads need the token as
every read of the station's data does (unless ``station serve --public-read``); the revert is a mutation
(token), refused with 409 while a session runs (a validation writes the file when it ends) or when the
history has no earlier calibration.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Depends
from fastapi.concurrency import run_in_threadpool

from api._auth import read_access, require_token
from api._deps import ScaleCalibrationsDep
from api._openapi import problems

router = APIRouter(prefix="/api/v1/station/scale-calibration")


@router.get("", dependencies=[Depends(read_access)], responses=problems(401, 403, 422, 503))
async def show(calibrations: ScaleCalibrationsDep) -> dict[str, Any]:
    """``{"file", "calibration", "entry"}``: the current scale calibration (its groove width, u, the
    validation session that wrote it and the checks it passed) and the history entry that made it
    current; ``calibration`` null when the station has none (it measures with the nominal width)."""
    return await run_in_threadpool(calibrations.status)


@router.get("/history", dependencies=[Depends(read_access)], responses=problems(401, 403, 422, 503))
async def history(calibrations: ScaleCalibrationsDep) -> dict[str, Any]:
    """``{"items"}``: every change of the scale calibration, newest first (``version``, ``written_at``,
    ``action`` validation | revert | found, ``calibration``, ``previous``, ``restores``)."""
    items = await run_in_threadpool(calibrations.history)
    return {"items": items}


@router.post(
    "/revert",
    dependencies=[Depends(require_token)],
    responses=problems(401, 403, 422, 503, s409="a session runs, or there is nothing to revert to"),
)
async def revert(calibrations: ScaleCalibrationsDep) -> dict[str, Any]:
    """Back to the calibration that was current before this one (or to none): the new history entry and
    the station's scale calibration now. 409 while a session runs, or with nothing to revert to."""
    return await run_in_threadpool(calibrations.revert)
