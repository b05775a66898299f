"""``POST /api/v1/station/robot/jog`` and ``POST /api/v1/station/teach/{reference, artifact/{name},
sensor-mount}``: jogging the arm and teaching the cell from the page or a script (issue 23).

Both make the arm move, so both need what ``to-reference`` needs: the token (a cookie only from the
station's own page), the station itself unless ``station serve --allow-remote-motion``
(``remote_motion``), no session running and nothing else moving the arm (409 ``conflict``), and no
latched stop (409 ``stop_latched``: acknowledge it at the station). The worker does the work
(``station.worker._teach``); every motion is checked by the robot before it is sent, so a refused jog
moves nothing. A teach writes the station's configuration file (comments kept, the old file backed up)
and answers the taught values with the backup's name.
"""

from __future__ import annotations

import contextlib
import logging
import math
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Path, Request
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel, ConfigDict, Field, field_validator

from api._auth import motion_access
from api._deps import SESSION_ID, service_of
from api._openapi import ARM_BUSY_409, MOTION_403, problems
from api._service import StationService, WorkerError
from station.jog import MAX_CAMERA_JOG_DEG, MAX_CAMERA_JOG_MM, MAX_JOINT_JOG_DEG

log = logging.getLogger(__name__)
router = APIRouter(prefix="/api/v1/station")

JOG_TIMEOUT_S = 120.0
"""The longest a jog may take in the worker (a jog of at most 10 deg at the jog speed)."""
TEACH_TIMEOUT_S = 900.0
"""The longest a teach may take in the worker (a few dozen small moves and readings)."""
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,39}$"
"""An artifact's name: what a person types, and what the configuration's ``artifact_names`` holds."""


def _finite(value: float) -> float:
    if not math.isfinite(value):
        raise ValueError("must be a finite number")
    return value


class JointJog(BaseModel):
    """Jog one joint (1-6) by ``delta_deg`` (deg, at most 10 either way)."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["joint"]
    joint: int = Field(ge=1, le=6)
    delta_deg: float = Field(ge=-MAX_JOINT_JOG_DEG, le=MAX_JOINT_JOG_DEG)

    _check = field_validator("delta_deg")(_finite)


class CameraJog(BaseModel):
    """Jog the camera in its own frame: ``x``/``y`` (the image's right/down, mm), ``z`` (along the optical
    axis, + toward what it looks at, mm), ``turn`` (about the optical axis, deg); ``delta`` at most 10
    (mm, or deg for ``turn``) either way."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["camera"]
    axis: Literal["x", "y", "z", "turn"]
    delta: float = Field(
        ge=-max(MAX_CAMERA_JOG_MM, MAX_CAMERA_JOG_DEG), le=max(MAX_CAMERA_JOG_MM, MAX_CAMERA_JOG_DEG)
    )

    _check = field_validator("delta")(_finite)


JogRequest = Annotated[JointJog | CameraJog, Field(discriminator="mode")]


class JogModel(BaseModel):
    """What a jog did: ``kind`` (``joint``, ``camera``), ``axis`` (the joint's number, or ``x``, ``y``,
    ``z``, ``turn``), ``delta`` in ``unit`` (``mm``, ``deg``), the commanded joints before
    (``start_joints_deg``) and asked for (``target_joints_deg``), the speed it ran at (``speed_pct``), and
    where the arm is now: ``joints_deg``, ``commanded_joints_deg``, ``world_mm_deg`` (the controller's
    WORLD: x, y, z mm and its three angles, deg; null when it does not give one)."""

    kind: Literal["joint", "camera"]
    axis: str
    delta: float
    unit: Literal["mm", "deg"]
    start_joints_deg: list[float]
    target_joints_deg: list[float]
    speed_pct: float
    joints_deg: list[float]
    commanded_joints_deg: list[float]
    world_mm_deg: list[float] | None


class TeachBody(BaseModel):
    """What a teach reads through: ``calibration_session``, a calibration session of this station that
    succeeded with its checks passed, with the controller the arm has now (its calibrated arm); no body
    (or no key): the nominal model."""

    model_config = ConfigDict(extra="forbid")

    calibration_session: str | None = Field(
        None, pattern=SESSION_ID, description="a calibration session's id (or a unique prefix of 4+)"
    )


class TaughtModel(BaseModel):
    """What a teach wrote: ``what`` (``reference``, ``artifact``, ``sensor-mount``), ``taught`` (the
    values: ``reference_joints_deg`` and ``crossing_mm``; an artifact's ``name``, ``position_mm``,
    ``normal``, ``turn_deg``, ``joints_deg``; the sensor mount's ``translation_z_mm``, ``slope``,
    ``rms_mm``, ``pairs_mm``; every one's ``model``: the arm model they were read through, ``{"model":
    "nominal"}`` or ``{"model": "calibrated", "calibration_session", "created"}``), ``config`` (the
    configuration file's name), ``backup`` (the old file's copy beside it) and ``changes`` (``key =
    value`` lines)."""

    what: Literal["reference", "artifact", "sensor-mount"]
    taught: dict[str, Any]
    config: str
    backup: str
    changes: list[str]


def _after_motion(service: StationService, call: str, *args: Any, timeout_s: float) -> dict[str, Any]:
    """``worker.call(call, *args)``, then the arm read again so that ``/station`` shows where it is."""
    try:
        done: dict[str, Any] = service.worker.call(call, *args, timeout_s=timeout_s)
    finally:
        with contextlib.suppress(Exception):  # the read's failure is the robot's state in ``/station``
            service.robot_state.read()
    return done


@router.post(
    "/robot/jog",
    response_model=JogModel,
    dependencies=[Depends(motion_access)],
    responses=problems(
        401,
        502,
        503,
        s403=MOTION_403,
        s409=ARM_BUSY_409,
        s422="a bad body (a joint outside 1-6, a step over 10 mm or deg, an unknown axis), or a jog the"
        " robot's checks refuse (limits, keep-out, speed cap, a singularity: ``motion_rejected``); nothing"
        " moved",
    ),
)
async def jog(request: Request, body: JogRequest) -> JogModel:
    """Jog the arm by one small step at the jog speed (``[robot] safety.jog_speed_pct``, default 10 %,
    never above the cell's ``max_speed_pct``): one joint (``{"mode": "joint", "joint": 1..6,
    "delta_deg": d}``), or the camera in its own frame through the station's nominal model (``{"mode":
    "camera", "axis": "x"|"y"|"z"|"turn", "delta": d}``, mm or deg). The target is checked (limits, step,
    keep-out along the path, speed cap) before anything is sent; answers once the arm has stopped."""
    service = service_of(request)
    done = await run_in_threadpool(_after_motion, service, "jog", body.model_dump(), timeout_s=JOG_TIMEOUT_S)
    return JogModel.model_validate(done)


_TEACH_422 = (
    "the readings cannot give the value (``teach_failed``: no crossing in view, out of the sensor's"
    " range ...), a move the robot's checks refuse (``motion_rejected``), a configuration that cannot"
    " take it (``configuration_error``), or a ``calibration_session`` that is not a calibration session"
    " on record (``calibration_session_invalid``); nothing was written"
)
_TEACH_409 = (
    ARM_BUSY_409 + "; the service has no configuration file to write (``not_available``); or the"
    " ``calibration_session`` cannot be taught through (``calibration_refused``: it did not succeed, a"
    " check failed, it ran on another station or controller, or with another camera mounting)"
)


def _taught(service: StationService, what: str, name: str | None, session: str | None) -> dict[str, Any]:
    """The teach, then ``/station``'s configuration taken again (the file and the worker's have changed)."""
    done = _after_motion(service, "teach", what, name, session, timeout_s=TEACH_TIMEOUT_S)
    try:
        service.config_changed()
    except (WorkerError, TimeoutError) as exc:  # written; /station shows the old values until a restart
        log.warning("the station's configuration could not be read again after the teach: %s", exc)
    return done


async def _teach(request: Request, what: str, name: str | None, body: TeachBody | None) -> TaughtModel:
    service = service_of(request)
    session = None if body is None else body.calibration_session
    done = await run_in_threadpool(_taught, service, what, name, session)
    return TaughtModel.model_validate(done)


@router.post(
    "/teach/reference",
    response_model=TaughtModel,
    dependencies=[Depends(motion_access)],
    responses=problems(401, 502, 503, s403=MOTION_403, s409=_TEACH_409, s422=_TEACH_422),
)
async def teach_reference(request: Request, body: TeachBody | None = None) -> TaughtModel:
    """Teach the reference pose: with the table's crossing in view (jog there first), the camera is
    focused by the distance sensor and moved until the crossing is on the principal point at the working
    distance, its orientation kept; the pose becomes ``[robot] reference_joints_deg``. Through the
    calibrated arm of ``{"calibration_session": id}`` when given."""
    return await _teach(request, "reference", None, body)


@router.post(
    "/teach/artifact/{name}",
    response_model=TaughtModel,
    dependencies=[Depends(motion_access)],
    responses=problems(401, 502, 503, s403=MOTION_403, s409=_TEACH_409, s422=_TEACH_422),
)
async def teach_artifact(
    request: Request,
    name: Annotated[
        str, Path(pattern=NAME_PATTERN, description="the artifact's name (1-40 of A-Z a-z 0-9 _ . -)")
    ],
    body: TeachBody | None = None,
) -> TaughtModel:
    """Teach artifact ``name`` (with its crossing in view): the camera squared to its plane (read by the
    sensor) and centred at the working distance; its crossing, normal and square turn go into
    ``[calibration]`` (in place of ``name``, or added). After the arm's calibration, teach it again
    through the calibrated arm (``{"calibration_session": id}``): the normal and turn then lose the
    arm's orientation error (in the calibrated arm's base frame, which its artifacts define)."""
    return await _teach(request, "artifact", name, body)


@router.post(
    "/teach/sensor-mount",
    response_model=TaughtModel,
    dependencies=[Depends(motion_access)],
    responses=problems(401, 502, 503, s403=MOTION_403, s409=_TEACH_409, s422=_TEACH_422),
)
async def teach_sensor_mount(request: Request, body: TeachBody | None = None) -> TaughtModel:
    """Teach the distance sensor's mount (the camera square to a flat surface and in focus, e.g. at the
    reference pose): the camera moved along its optical axis over known heights, the sensor read at
    each; its offset along the axis goes into ``[distance_sensor] mount``. Through the calibrated arm
    of ``{"calibration_session": id}`` when given."""
    return await _teach(request, "sensor-mount", None, body)
