"""Fixtures: a controllable target, the IL twin on a real pty reading it, and every DistanceSensor
implementation the contract suite runs against (the driver on the twin; the in-process fake)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from drivers.keyence_il import KeyenceIL, LinkSettings
from sim.distance_sensor import DistanceSensorTwin, HeadModel
from station.devices import DistanceSensor
from station.testing import FakeDistanceSensor

# A lost reply costs a fraction of a second, not the real second.
FAST_LINK = LinkSettings(reply_timeout_s=0.3)


@dataclass
class Target:
    """A flat target facing the head: ``distance_mm`` along the beam, tilted ``tilt_deg`` about x,
    ``present`` False: moved sideways out of the beam."""

    distance_mm: float = 70.0
    tilt_deg: float = 0.0
    present: bool = True

    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        head = np.eye(4)
        plane = np.eye(4)
        t = math.radians(self.tilt_deg)
        plane[:3, :3] = np.array([[1, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])
        plane[:3, 3] = (0.0, 0.0 if self.present else 500.0, self.distance_mm)
        return head, plane

    def distance(self) -> float | None:
        return self.distance_mm if self.present else None


@pytest.fixture
def target() -> Target:
    return Target()


@pytest.fixture
def make_twin(target: Target) -> Iterator[Callable[..., DistanceSensorTwin]]:
    twins: list[DistanceSensorTwin] = []

    def make(**head: Any) -> DistanceSensorTwin:
        twin = DistanceSensorTwin(target.poses, HeadModel.model_validate(head), seed=1).start()
        twins.append(twin)
        return twin

    yield make
    for twin in twins:
        twin.close()


@pytest.fixture
def twin(make_twin: Callable[..., DistanceSensorTwin]) -> DistanceSensorTwin:
    return make_twin()


@pytest.fixture
def driver_on(twin: DistanceSensorTwin) -> Iterator[Callable[..., KeyenceIL]]:
    sensors: list[KeyenceIL] = []

    def make(**options: Any) -> KeyenceIL:
        options.setdefault("link", FAST_LINK)
        sensor = KeyenceIL(twin.port, **options)
        sensors.append(sensor)
        return sensor

    yield make
    for s in sensors:
        s.close()


IMPLEMENTATIONS = ("driver_on_twin", "fake")


@dataclass
class Subject:
    """One implementation under the contract, with the means to make it fail as its kind can."""

    sensor: DistanceSensor
    set_alarm: Callable[[bool], None]
    noise_mm: float


@pytest.fixture(params=IMPLEMENTATIONS)
def subject(request: pytest.FixtureRequest, target: Target) -> Subject:
    if request.param == "driver_on_twin":
        twin: DistanceSensorTwin = request.getfixturevalue("twin")
        driver = request.getfixturevalue("driver_on")()
        return Subject(driver, twin.set_alarm, 0.01)
    fake = FakeDistanceSensor(target.distance)

    def alarm(on: bool) -> None:
        fake.alarm = on

    return Subject(fake, alarm, 0.0)
