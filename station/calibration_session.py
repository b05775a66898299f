"""A compensated camera move (``station robot ... move-camera``): the camera to a pose with a calibrated
model. The calibration kind itself lives in :mod:`station.kinds.calibration`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy.typing as npt

from station.arm_route import quantised, split_move, travel
from station.calibration import compensated_joints

if TYPE_CHECKING:
    from station.devices import Robot
    from station.kinematics import Kinematics


def move_camera(
    robot: Robot,
    calibrated: Kinematics,
    camera_pose: npt.ArrayLike,
    *,
    max_step_deg: float,
    through_lift: bool = False,
) -> list[tuple[float, ...]]:
    """A compensated move: the camera to ``camera_pose`` (4x4, the calibrated model's base frame, mm) by
    inverse kinematics with the calibrated model, sent as joint moves within ``max_step_deg`` each:
    straight in joint space, or with ``through_lift`` up, across and down through the lift poses (the
    calibration plan's route between artifacts).

    The whole chain of waypoints is checked with ``check_move`` before the first is sent (a chain that
    fails validation moves nothing). Returns the waypoints sent (deg, at the controller's resolution).
    """
    start = tuple(float(a) for a in robot.where().commanded_joints_deg)
    target = quantised(compensated_joints(calibrated, camera_pose, current_deg=start))
    steps = (travel if through_lift else split_move)(start, target, max_step_deg)
    previous = start
    for q in steps:
        robot.check_move(q, start_deg=previous)
        previous = q
    for q in steps:
        robot.move_joints(q)
    return steps


__all__ = ["move_camera"]
