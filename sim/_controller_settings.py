"""The controller twin's settings (``TwinSettings``): how the simulated C500C behaves, validated.

Speeds, accelerations and encoder counts: drivers/crs_a465/DIALECT.md [A]; the joints' attained error
model: ``sim.arm_errors``.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from sim._controller_faults import Fault, parse_fault
from sim.arm_errors import DEFAULT_ARM_ERRORS
from station.devices import Joints6
from station.kinematics import A465_JOINT_LIMITS_DEG


def _six(value: Any) -> Any:
    """Accept one number for all six joints."""
    if isinstance(value, int | float):
        return (float(value),) * 6
    return value


class TwinSettings(BaseModel):
    """How the twin behaves. Speeds, accelerations and encoder counts: drivers/crs_a465/DIALECT.md [A]."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    shell: Literal["system", "application"] = "system"
    app_name: str = Field("ash", pattern=r"^\S+$")
    echo: bool = True
    motion_blocks: bool = Field(
        False,
        description="False: the firmware's behaviour (prompt at once); True: prompt when the motion ends",
    )
    ctrl_c_stops: bool = Field(False, description="True: Ctrl-C stops a motion (not the firmware's) [A]")
    log_limit: int = Field(1000, ge=1, description="received lines and motions kept (the last N)")
    time_scale: float = Field(1.0, gt=0, description="100 runs every motion 100x faster than real")
    seed: int | None = Field(None, description="random repeatability error; None: fresh entropy")
    power: bool = True
    homed: bool = True
    speed_pct: int = Field(50, ge=1, le=100)
    max_speed_deg_s: Joints6 = (180.0, 180.0, 180.0, 172.0, 172.0, 172.0)
    accel_deg_s2: Joints6 = (720.0, 720.0, 720.0, 1430.0, 1430.0, 1430.0)
    counts_per_deg: Joints6 = (
        400000 / 360,
        400000 / 360,
        400000 / 360,
        200000 / 360,
        200000 / 360,
        200000 / 360,
    )
    # the joint part of sim.arm_errors' model fitted to the seed's Table 2 (the Cartesian part is the world's)
    repeat_sigma_deg: Joints6 = Field(
        DEFAULT_ARM_ERRORS.joints.sigma_deg, description="random part of the attained error (1 sigma)"
    )
    systematic_deg: Joints6 = Field((0.0,) * 6, description="constant part of the attained error")
    backlash_deg: Joints6 = Field(
        DEFAULT_ARM_ERRORS.joints.backlash_deg, description="attained error signed by the approach direction"
    )
    settle_deg: Joints6 = Field(
        DEFAULT_ARM_ERRORS.joints.settle_deg, description="servo residual at the motion's end (1 sigma)"
    )
    settle_time_s: float = Field(
        DEFAULT_ARM_ERRORS.joints.settle_time_s, gt=0, description="the residual's decay time (model s)"
    )
    joint_limits_deg: tuple[tuple[float, float], ...] = A465_JOINT_LIMITS_DEG
    home_pose_deg: Joints6 = (0.0,) * 6
    ready_pose_deg: Joints6 = (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    start_pose_deg: Joints6 | None = Field(None, description="where the arm starts; None: the ready pose")
    homing_extra_s: float = Field(2.0, ge=0, description="index search time added to home")
    link: str | None = Field(
        None, description="a symlink kept pointing at the current pty ('auto': in a temporary directory)"
    )
    faults: tuple[Fault, ...] = ()
    line_baud: int | None = Field(
        None,
        gt=0,
        description="pace what the twin sends as a serial line of this speed would (8N1: 10 bits a"
        " byte; the C500C's console runs at 57600); None: as fast as the pty (default)",
    )

    @field_validator("repeat_sigma_deg", "systematic_deg", "backlash_deg", "settle_deg", mode="before")
    @classmethod
    def _broadcast(cls, value: Any) -> Any:
        return _six(value)

    @field_validator("faults", mode="before")
    @classmethod
    def _parse_faults(cls, value: Any) -> Any:
        if isinstance(value, list | tuple):
            return tuple(parse_fault(v) if isinstance(v, str) else v for v in value)
        return value


__all__ = ["TwinSettings"]
