"""The arm as the worker reads and moves it between sessions, in one connection each (connect, act,
close): its status against the reference pose, and the route there (``station.arm_route``)."""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

from station.arm_route import ArmPose, ToReferenceResult, go_to_reference, robot_status
from station.devices import Robot


def read_arm(robot: Robot, reference: tuple[float, ...] | None, max_step_deg: float) -> dict[str, Any]:
    """``identity``, ``power``, ``homed``, the position and, with a reference pose, where it is against
    it and the route ``to-reference`` would take (``reference_joints_deg``, ``at_reference``,
    ``route``; None without one). Nothing moves."""
    robot.connect()
    try:
        status, identity = robot.status(), robot.identity()
        if reference is not None:
            arm = robot_status(robot, reference, max_step_deg)
            position = arm.position
            against: dict[str, Any] = {
                "reference_joints_deg": arm.reference_joints_deg,
                "at_reference": arm.at_reference,
                "route": arm.route.model_dump(mode="json"),
            }
        else:
            position = ArmPose.of(robot.where())
            against = {"reference_joints_deg": None, "at_reference": None, "route": None}
    finally:
        robot.close()
    return {
        "identity": asdict(identity),
        "power": status.power,
        "homed": status.homed,
        **position.model_dump(mode="json"),
        **against,
    }


def arm_to_reference(robot: Robot, reference: tuple[float, ...], max_step_deg: float) -> ToReferenceResult:
    """The arm to ``reference`` along its route, every move checked before the first is sent (an
    operator's command: it clears a latched stop, as a session's start does)."""
    robot.connect()
    try:
        robot.clear_stop()
        return go_to_reference(robot, reference, max_step_deg=max_step_deg)
    finally:
        robot.close()
