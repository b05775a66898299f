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
from station.prompts import PromptBroker, PromptEvent
from station.table_content import PROMPT_KIND as TABLE_CONTENT_KIND
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

    table_content: str = "cross"
    """What lies on the fake table: its scene shows the crossing. A session asking for it
    (``station.table_content``) has it confirmed at once; asking for anything else is declined."""

    def __post_init__(self) -> None:
        if self.camera is None:
            self.camera = FakeCamera(
                scene=Scene(robot=self.robot, table=self.table, reference_deg=tuple(self.robot.joints))
            )
        self.broker.subscribe(self._answer_table_content)

    def _answer_table_content(self, event: PromptEvent) -> None:
        """The fake's operator: what lies on its table is what it has (no one puts anything else there)."""
        p = event.prompt
        if event.kind != "opened" or p.kind != TABLE_CONTENT_KIND:
            return
        if p.details.get("content") == self.table_content:
            self.broker.confirm(p.id, by="fake-station")
        else:
            holds = f"the fake table holds the {self.table_content}"
            self.broker.cancel(p.id, reason=holds, by="fake-station")

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
