"""The arm as the worker reads and moves it between sessions, in one connection each (connect, act,
close): its status against the reference pose, and the route there (``station.arm_route``)."""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

from station.arm_route import ArmPose, ToReferenceResult, go_to_reference, robot_status
from station.devices import Robot, StopLatchedError
from station.local_ack import LocalAcknowledgement


def latch_reason(robot: Robot) -> str | None:
    """What latched the robot's stop (``None``: not latched), asked through the interface: ``clear_stop``
    releases nothing and raises StopLatchedError, with the reason, while a stop is latched."""
    try:
        robot.clear_stop()
    except StopLatchedError as exc:
        return exc.reason or str(exc)
    return None


def read_arm(robot: Robot, reference: tuple[float, ...] | None, max_step_deg: float) -> dict[str, Any]:
    """``identity``, ``power``, ``homed``, ``latched`` (what latched its stop, None), the position and,
    with a reference pose, where it is against
    it and the route ``to-reference`` would take (``reference_joints_deg``, ``at_reference``,
    ``route``; None without one). Nothing moves."""
    robot.connect()
    try:
        status, identity = robot.status(), robot.identity()
        latched = latch_reason(robot)
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
        "latched": latched,
        **position.model_dump(mode="json"),
        **against,
    }


def arm_to_reference(robot: Robot, reference: tuple[float, ...], max_step_deg: float) -> ToReferenceResult:
    """The arm to ``reference`` along its route, every move checked before the first is sent; a latched
    stop is not cleared (StopLatchedError: acknowledge it at the station first)."""
    robot.connect()
    try:
        robot.clear_stop()  # releases nothing: raises while a stop is latched
        return go_to_reference(robot, reference, max_step_deg=max_step_deg)
    finally:
        robot.close()


def acknowledge_arm(robot: Robot, peer_host: str | None) -> dict[str, Any]:
    """Release the robot's stop latch for a request from ``peer_host`` (the connection's peer), which
    must be loopback (RemoteAcknowledgementError otherwise: nothing released)."""
    ack = LocalAcknowledgement.from_loopback(peer_host)
    robot.connect()
    try:
        reason = robot.acknowledge_stop(ack)
    finally:
        robot.close()
    return {"acknowledged": reason is not None, "reason": reason}
