"""What a plan's analysis reads of the station's configuration: the arm's reference pose and the camera's
height above the artifact plane (from the robot's safety settings and the nominal kinematics); and what
it reads of a stored session: its captures with the measurements a session recorded of them
(``stored_captures``).

While a session runs, the runner reads them from the station's configuration (``station.runner``). When a
stored session is measured again (``reanalyse``), its plan reads them from the configuration the session
recorded (its ``config`` snapshot): a re-analysis computes what the session computed, whatever the station
is configured with today (or without any station at all), and moves nothing.

Only the plans' interfaces and the kinematics are imported here: every plan, the runner and the
re-analysis may use it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from station.plans import CaptureResult, PlanContext, PlanError

if TYPE_CHECKING:
    from station.record import MeasurementRow, Record

HeightFunction = Callable[[Sequence[float]], float]


def robot_section(config: Mapping[str, Any] | None) -> Mapping[str, Any]:
    """The ``robot`` section of a configuration (a ``StationConfig`` as JSON, or a session's snapshot)."""
    robot = (config or {}).get("robot")
    return robot if isinstance(robot, Mapping) else {}


def reference_of(config: Mapping[str, Any] | None) -> tuple[float, ...] | None:
    """The reference pose (deg) a configuration gives its robot, None without one."""
    ref = robot_section(config).get("reference_joints_deg")
    return None if ref is None else tuple(float(a) for a in ref)


def camera_height_function(safety: Mapping[str, Any] | None) -> HeightFunction | None:
    """Height (mm) of the camera's front above the artifact plane for given joints, from the robot's
    safety settings (``table_z_mm``, ``camera_offset_mm``) and the nominal kinematics; None when they do
    not say."""
    safety = safety or {}
    if "table_z_mm" not in safety or "camera_offset_mm" not in safety:
        return None
    from station.kinematics import Kinematics

    kin = Kinematics()
    offset = np.array([*safety["camera_offset_mm"], 1.0], dtype=np.float64)
    z0 = float(safety["table_z_mm"])

    def height(joints: Sequence[float]) -> float:
        return float((kin.forward(joints) @ offset)[2]) - z0

    return height


def camera_height_of(config: Mapping[str, Any] | None) -> HeightFunction | None:
    """:func:`camera_height_function` of a configuration's robot."""
    safety = robot_section(config).get("safety")
    return camera_height_function(safety if isinstance(safety, Mapping) else None)


__all__ = ["HeightFunction", "camera_height_function", "camera_height_of", "reference_of", "robot_section"]


def record_of(ctx: PlanContext) -> Record:
    """The record an offline plan reads its stored session from; PlanError without one."""
    if ctx.record is None:
        raise PlanError("this plan reads a stored session: it needs the record")
    return ctx.record


FRAMES_PER_ATTEMPT = 1000
"""A step's frames are numbered from attempt x FRAMES_PER_ATTEMPT (plans capture at most 100 per step)."""


def stored_captures(
    record: Record,
    source: str,
    *,
    measured_in: str | None = None,
    measurements: Mapping[int, MeasurementRow] | None = None,
) -> list[CaptureResult]:
    """The captures of session ``source``'s completed steps with the measurements session ``measured_in``
    recorded of them (the source's own by default): what a plan's analysis gets."""
    if measurements is None:  # given: read once for several sources (an archive selection's)
        measurements = {m.capture_id: m for m in record.measurements(measured_in or source)}
    done = {s.index for s in record.steps(source) if s.state == "done"}
    caps = [c for c in record.captures(source) if c.step_index in done]
    # a step run again after an interruption keeps its earlier attempt's frames (nothing captured is
    # lost); the analysis takes the attempt that completed: the latest
    latest: dict[int, int] = {}
    for c in caps:
        latest[c.step_index] = max(latest.get(c.step_index, 0), c.frame_index // FRAMES_PER_ATTEMPT)
    out = []
    for cap in caps:
        if cap.frame_index // FRAMES_PER_ATTEMPT != latest[cap.step_index]:
            continue
        m = measurements.get(cap.id)
        out.append(
            CaptureResult(
                cap.id,
                cap.step_index,
                cap.frame_index,
                cap.meta,
                m.result if m else None,
                cap.width,
                cap.height,
                cap.z_mm,
            )
        )
    return out
