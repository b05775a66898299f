"""``FakeStation``: a fake robot, camera and table wired through one ``Scene``, as ``StationDevices``."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from station.config import (
    CameraConfig,
    DistanceSensorConfig,
    RobotConfig,
    StationConfig,
    StationDevices,
    TableConfig,
)
from station.prompts import PromptBroker
from station.testing._camera import FakeCamera, Scene
from station.testing._robot import FakeRobot
from station.testing._sensor import FakeDistanceSensor
from station.testing._table import FakeTable

FloatArray = npt.NDArray[np.float64]


@dataclass
class FakeStation:
    """A fake robot, camera and table wired through one ``Scene``, as ``StationDevices``."""

    robot: FakeRobot = field(default_factory=FakeRobot)
    table: FakeTable = field(default_factory=FakeTable)
    camera: FakeCamera | None = None
    broker: PromptBroker = field(default_factory=PromptBroker)
    distance_sensor: FakeDistanceSensor | None = None

    def __post_init__(self) -> None:
        if self.camera is None:
            self.camera = FakeCamera(
                scene=Scene(robot=self.robot, table=self.table, reference_deg=tuple(self.robot.joints))
            )

    @property
    def cam(self) -> FakeCamera:
        """The fake camera (built in ``__post_init__`` when not given)."""
        assert self.camera is not None
        return self.camera

    def devices(self) -> StationDevices:
        assert self.camera is not None
        config = StationConfig(
            name="fake",
            robot=RobotConfig(driver="fake", reference_joints_deg=tuple(self.robot.joints)),
            camera=CameraConfig(driver="fake"),
            table=TableConfig(driver="fake", prompts="api"),
            distance_sensor=None if self.distance_sensor is None else DistanceSensorConfig(driver="fake"),
        )
        return StationDevices(
            config=config,
            camera=self.camera,
            broker=self.broker,
            robot=self.robot,
            table=self.table,
            distance_sensor=self.distance_sensor,
        )


__all__ = [
    "FakeStation",
]
