"""``GET /api/v1/station/safety``: which of the station's safety rules are in force (issue 23, item 4), for
the page's "Safety in force" panel and a lab officer's script: the keep-out volumes, the speed cap, the
stop latch and how it is released, and whether clients on other machines may make the arm move."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Depends, Request
from pydantic import BaseModel

from api._auth import Access, may_move, peer_is_local, read_access
from api._deps import Reads
from api._openapi import problems
from station.jog import JOG_SPEED_PCT
from station.speed_cap import DEFAULT_MAX_SPEED_PCT, SPEED_CAP_SETTING

router = APIRouter(prefix="/api/v1/station")

ACKNOWLEDGE_HOW = (
    "look at the arm and the cell, then press 'acknowledge the stop' in this page opened on the station"
    " itself (http://127.0.0.1:PORT/), or run station robot --config FILE acknowledge at its terminal"
)


class SafetyModel(BaseModel):
    """The rules in force.

    ``robot``: whether the station has a robot (without one, the rest is moot); ``keep_out_volumes``: how
    many configured keep-out volumes (boxes and cylinders, ``[robot] safety.keep_out``) every path is
    checked against, besides the table plane and the camera's minimum height (``min_camera_height_mm``);
    ``max_speed_pct``: the speed cap no plan, jog or Align exceeds, and ``speed_cap_setting`` where it is
    set; ``jog_speed_pct``: the speed jogs and teaching run at; ``latched``: what latched the robot's stop
    (null: not latched); ``local_acknowledgement``: a latched stop is released only by a person at the
    station (always true), ``acknowledge_how`` says how; ``remote_motion``: whether clients on other
    machines may make the arm move (``station serve --allow-remote-motion``); ``local`` and ``motion``:
    whether this client is on the station itself, and may make the arm move.
    """

    robot: bool
    keep_out_volumes: int
    min_camera_height_mm: float | None
    max_speed_pct: float
    speed_cap_setting: str
    jog_speed_pct: float
    latched: str | None
    local_acknowledgement: bool
    acknowledge_how: str
    remote_motion: bool
    local: bool
    motion: bool


@router.get(
    "/safety",
    response_model=SafetyModel,
    dependencies=[Depends(read_access)],
    responses=problems(401, 403),
)
async def safety(request: Request, reads: Reads) -> SafetyModel:
    """Which safety rules are in force, from the station's configuration and the robot's latest read;
    never touches a device."""
    station = reads.station()
    config: dict[str, Any] = station.get("config") or {}
    robot_config: dict[str, Any] = config.get("robot") or {}
    rules: dict[str, Any] = robot_config.get("safety") or {}
    robot_doc: dict[str, Any] = station.get("robot") or {}
    access: Access = request.app.state.access
    height = rules.get("min_camera_height_mm")
    return SafetyModel(
        robot=bool(robot_config),
        keep_out_volumes=len(rules.get("keep_out") or []),
        min_camera_height_mm=None if height is None else float(height),
        max_speed_pct=float(rules.get("max_speed_pct", DEFAULT_MAX_SPEED_PCT)),
        speed_cap_setting=SPEED_CAP_SETTING,
        jog_speed_pct=float(rules.get("jog_speed_pct", JOG_SPEED_PCT)),
        latched=robot_doc.get("latched"),
        local_acknowledgement=True,
        acknowledge_how=ACKNOWLEDGE_HOW,
        remote_motion=access.remote_motion,
        local=peer_is_local(request),
        motion=may_move(request),
    )
