"""Driver for the CRS A465 arm on a C500C controller (CROS system shell or the ``ash`` application shell).

Build one by name through the station's registry (not connected: call ``connect()``)::

    robot = station.config.build("robot", "crs_a465", port="/dev/ttyS0")
    robot = station.config.build("robot", "crs_a465", port=twin.port, safety={"max_step_deg": 10})
    robot.connect()

or directly with :func:`open_robot` / :class:`CrsA465`. The dialect and what is known of it:
``drivers/crs_a465/DIALECT.md``; every assumption is a setting of :class:`LinkSettings`,
:class:`ShellProfile`, :class:`MotionSettings` or :class:`SafetyLimits`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any, Literal

import serial

from drivers.crs_a465._commands import Request, ShellProfile
from drivers.crs_a465._errors import (
    ERROR_TEXTS,
    ArmPowerOffError,
    ArrivalError,
    AxisLimpError,
    AxisLockedError,
    CollisionError,
    CommandNotAvailableError,
    ControllerBusyError,
    ControllerUsageError,
    CrsControllerError,
    EncoderAlarmError,
    HomingError,
    IllegalSpeedError,
    InvalidArgumentError,
    JointLimitError,
    LockedOutError,
    MotionAbortedError,
    MotionFaultError,
    NotHomedError,
    NotOnlineError,
    OutOfReachError,
    PointOfControlError,
    RaplExceptionError,
    ServoError,
    StanceError,
    UnexpectedReplyError,
    UnknownCommandError,
    UnmappedCodeError,
)
from drivers.crs_a465._link import LinkSettings, SerialTransport
from drivers.crs_a465._motion import MotionSettings
from drivers.crs_a465._replies import ArmStat, AxisState, PositionReport
from drivers.crs_a465._robot import Arrival, CrsA465
from drivers.crs_a465._safety import MotionGuard, PlannedMove, SafetyLimits
from station.devices import Robot
from station.kinematics import Kinematics


def build_robot(
    port: str | serial.SerialBase,
    *,
    shell: Literal["system", "application"] | ShellProfile = "system",
    app_name: str = "ash",
    baudrate: int | None = None,
    link: LinkSettings | Mapping[str, Any] | None = None,
    safety: SafetyLimits | Mapping[str, Any] | None = None,
    motion: MotionSettings | Mapping[str, Any] | None = None,
    kinematics: Kinematics | None = None,
    latch_file: str | os.PathLike[str] | None = None,
) -> CrsA465:
    """Build an unconnected :class:`CrsA465` from plain configuration values (all validated here).

    ``shell`` is ``"system"`` (``$ `` prompt) or ``"application"`` (``APP_NAME> `` prompt);
    ``link``, ``safety`` and ``motion`` take the fields of :class:`LinkSettings`, :class:`SafetyLimits`
    and :class:`MotionSettings`; ``baudrate`` overrides ``link``'s; ``latch_file`` keeps the stop latch
    across processes (the station's data directory). Raises pydantic's ValidationError
    (a ValueError) or InvalidArgumentError on a bad value; nothing is opened.
    """
    link_values = link.model_dump() if isinstance(link, LinkSettings) else dict(link or {})
    if baudrate is not None:
        link_values["baudrate"] = baudrate
    link_settings = LinkSettings.model_validate(link_values)
    if isinstance(shell, ShellProfile):
        profile = shell
    elif shell == "system":
        profile = ShellProfile.system()
    elif shell == "application":
        profile = ShellProfile.application(app_name)
    else:
        raise InvalidArgumentError(f"shell must be 'system' or 'application', got {shell!r}")
    limits = safety if isinstance(safety, SafetyLimits) else SafetyLimits.model_validate(dict(safety or {}))
    timing = (
        motion if isinstance(motion, MotionSettings) else MotionSettings.model_validate(dict(motion or {}))
    )
    return CrsA465(
        port,
        link=link_settings,
        shell=profile,
        safety=limits,
        motion=timing,
        kinematics=kinematics,
        latch_file=latch_file,
    )


def open_robot(
    port: str | serial.SerialBase,
    *,
    shell: Literal["system", "application"] | ShellProfile = "system",
    app_name: str = "ash",
    baudrate: int | None = None,
    link: LinkSettings | Mapping[str, Any] | None = None,
    safety: SafetyLimits | Mapping[str, Any] | None = None,
    motion: MotionSettings | Mapping[str, Any] | None = None,
    kinematics: Kinematics | None = None,
    latch_file: str | os.PathLike[str] | None = None,
) -> Robot:
    """The station's factory (``robot.crs_a465``): an unconnected robot; call ``connect()`` on it.

    Same arguments as :func:`build_robot`.
    """
    return build_robot(
        port,
        shell=shell,
        app_name=app_name,
        baudrate=baudrate,
        link=link,
        safety=safety,
        motion=motion,
        kinematics=kinematics,
        latch_file=latch_file,
    )


__all__ = [
    "ERROR_TEXTS",
    "ArmPowerOffError",
    "ArmStat",
    "Arrival",
    "ArrivalError",
    "AxisLimpError",
    "AxisLockedError",
    "AxisState",
    "CollisionError",
    "CommandNotAvailableError",
    "ControllerBusyError",
    "ControllerUsageError",
    "CrsA465",
    "CrsControllerError",
    "EncoderAlarmError",
    "HomingError",
    "IllegalSpeedError",
    "InvalidArgumentError",
    "JointLimitError",
    "LinkSettings",
    "LockedOutError",
    "MotionAbortedError",
    "MotionFaultError",
    "MotionGuard",
    "MotionSettings",
    "NotHomedError",
    "NotOnlineError",
    "OutOfReachError",
    "PlannedMove",
    "PointOfControlError",
    "PositionReport",
    "RaplExceptionError",
    "Request",
    "SafetyLimits",
    "SerialTransport",
    "ServoError",
    "ShellProfile",
    "StanceError",
    "UnexpectedReplyError",
    "UnknownCommandError",
    "UnmappedCodeError",
    "build_robot",
    "open_robot",
]
