"""The arm's interface: ``Robot``, its status and position."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from station.devices._lifecycle import DeviceIdentity
from station.local_ack import LocalAcknowledgement

JOINT_COUNT = 6

Joints6 = tuple[float, float, float, float, float, float]
"""One value per joint of the six-axis arm (deg, deg/s, ...): the one name of that type everywhere."""


@dataclass(frozen=True)
class RobotStatus:
    """What the controller reports; a field it cannot report is ``None`` (unknown), never a guess.

    ``speed_pct`` is the speed override (percent of maximum); ``last_error`` the last controller error
    text this connection saw (``None`` when there was none).
    """

    power: bool | None
    homed: bool | None
    moving: bool | None
    speed_pct: float | None
    last_error: str | None = None
    calibrated: bool | None = None
    arm_type: str | None = None


@dataclass(frozen=True)
class RobotPosition:
    """Joint angles (deg) attained and commanded, and the controller's WORLD row.

    ``joints_deg`` is the attained (encoder) position, ``commanded_joints_deg`` the set-point.
    ``world_mm_deg`` is ``(x, y, z, z_rot, y_rot, x_rot)`` as the controller prints it for the attained
    position (mm, deg), or ``None`` where the controller does not report it.
    """

    joints_deg: tuple[float, ...]
    commanded_joints_deg: tuple[float, ...]
    world_mm_deg: tuple[float, ...] | None = None


@runtime_checkable
class Robot(Protocol):
    """A six-joint arm moved in joint space (degrees).

    Every motion is checked on the host (joint limits, maximum step, keep-out) before anything is
    sent: a rejected motion raises ``MotionRejectedError`` and leaves the arm untouched; ``check_move``
    runs the same checks without any I/O. Motions return when the arm has arrived; ``wait_settled``
    blocks until an arm moved by someone else is still. Controller refusals raise ``ControllerError``
    subclasses; a lost link ``DeviceConnectionError`` (``connect()`` again re-reads the arm state).
    ``stop()``, a halt, an E-stop or a controller error during a motion latch: until a person at the
    station acknowledges it (``acknowledge_stop``), every motion raises ``StopLatchedError``.
    """

    def connect(self) -> None:
        """Open the link and read the arm's state."""

    def close(self) -> None:
        """Release the link; safe to call twice."""

    def status(self) -> RobotStatus:
        """Power, homing, motion and speed as the controller reports them."""

    def where(self) -> RobotPosition:
        """Attained and commanded joint angles (and the WORLD row where known)."""

    def move_joint(self, axis: int, delta_deg: float) -> None:
        """Move one joint (1-6) by ``delta_deg`` relative to where it is commanded now."""

    def move_joints(self, target_deg: Sequence[float]) -> None:
        """Move to six absolute joint angles (deg)."""

    def home(self) -> None:
        """Home the arm."""

    def ready(self) -> None:
        """Go to the controller's ready pose."""

    def set_speed(self, percent: float) -> None:
        """Set the speed override, in percent of maximum."""

    def check_move(self, target_deg: Sequence[float], *, start_deg: Sequence[float] | None = None) -> None:
        """Raise what ``move_joints(target_deg)`` from ``start_deg`` would raise on the host, with no I/O.

        ``start_deg`` ``None``: the last commanded position. Limits, step and keep-out only: a chain of
        moves can be checked before the first is sent.
        """

    def stop(self) -> None:
        """Stop any motion now, best effort (callable from another thread); latches until ``clear_stop``."""

    def clear_stop(self) -> None:
        """Release nothing: raise ``StopLatchedError`` when a stop is latched (what to do in its message),
        do nothing otherwise. A session's start calls it, so that no session clears a latch itself."""

    def acknowledge_stop(self, ack: LocalAcknowledgement) -> str | None:
        """Release the latch with a person's acknowledgement at the station; return what had latched it.

        Anything but a fresh, unused ``LocalAcknowledgement`` raises
        ``station.local_ack.RemoteAcknowledgementError`` and releases nothing.
        """

    def check_speed(self, percent: float) -> None:
        """Raise what ``set_speed(percent)`` would raise on the host (the speed cap), with no I/O."""

    def identity(self) -> DeviceIdentity:
        """Model, serial, port and firmware as far as the device reports them."""

    def wait_settled(self, timeout_s: float | None = None) -> None:
        """Block until the arm has stopped moving (raise DeviceTimeoutError after ``timeout_s``)."""


__all__ = [
    "JOINT_COUNT",
    "Robot",
    "RobotPosition",
    "RobotStatus",
]
