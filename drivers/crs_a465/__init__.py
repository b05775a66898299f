"""Driver for the CRS A465 arm on a C500C controller (CROS system shell or the ``ash`` application shell).

Build one by name through the station's registry::

    robot = station.config.build("robot", "crs_a465", port="/dev/ttyS0")        # connected
    robot = station.config.build("robot", "crs_a465", port=twin.port, safety={"max_step_deg": 10})

or directly with :func:`open_robot` / :class:`CrsA465`. The dialect and what is known of it:
``docs/crs-c500c-protocol.md``; every assumption is a setting of :class:`LinkSettings`,
:class:`ShellProfile` or :class:`SafetyLimits`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import serial

from drivers.crs_a465._commands import Request, ShellProfile
from drivers.crs_a465._errors import (
    ERROR_TEXTS,
    ArmPowerOffError,
    AxisLimpError,
    CollisionError,
    CrsControllerError,
    IllegalSpeedError,
    InvalidArgumentError,
    JointLimitError,
    NotHomedError,
    NotOnlineError,
    OutOfReachError,
    PointOfControlError,
    RaplExceptionError,
    UnknownCommandError,
)
from drivers.crs_a465._link import LinkSettings, SerialTransport
from drivers.crs_a465._replies import ArmStat, PositionReport
from drivers.crs_a465._robot import CrsA465
from drivers.crs_a465._safety import MotionGuard, PlannedMove, SafetyLimits
from station.kinematics import Kinematics


def open_robot(
    port: str | serial.SerialBase,
    *,
    shell: Literal["system", "application"] | ShellProfile = "system",
    app_name: str = "ash",
    baudrate: int | None = None,
    link: LinkSettings | Mapping[str, Any] | None = None,
    safety: SafetyLimits | Mapping[str, Any] | None = None,
    kinematics: Kinematics | None = None,
    connect: bool = True,
) -> CrsA465:
    """Build a :class:`CrsA465` from plain configuration values and (by default) connect it.

    ``shell`` is ``"system"`` (``$ `` prompt) or ``"application"`` (``APP_NAME> `` prompt, ``armstat``);
    ``link`` and ``safety`` take the fields of :class:`LinkSettings` and :class:`SafetyLimits`;
    ``baudrate`` overrides ``link``'s.
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
    robot = CrsA465(port, link=link_settings, shell=profile, safety=limits, kinematics=kinematics)
    if connect:
        robot.connect()
    return robot


__all__ = [
    "ERROR_TEXTS",
    "ArmPowerOffError",
    "ArmStat",
    "AxisLimpError",
    "CollisionError",
    "CrsA465",
    "CrsControllerError",
    "IllegalSpeedError",
    "InvalidArgumentError",
    "JointLimitError",
    "LinkSettings",
    "MotionGuard",
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
    "ShellProfile",
    "UnknownCommandError",
    "open_robot",
]
