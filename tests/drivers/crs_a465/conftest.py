"""Fixtures: a robot on a scripted port (exact exchanges), and controller twins on real ptys."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from drivers.crs_a465 import CrsA465, LinkSettings, SafetyLimits, ShellProfile
from sim.controller import ControllerTwin
from tests.drivers.crs_a465.fakes import Exchange, ScriptedPort

# Short timeouts: a dropped reply costs a fraction of a second, not the real 3 s.
FAST_LINK = LinkSettings(reply_timeout_s=0.3, motion_timeout_s=0.5, home_timeout_s=0.5, resync_quiet_s=0.02)


@pytest.fixture
def scripted() -> Iterator[Callable[..., tuple[CrsA465, ScriptedPort]]]:
    """``scripted(exchanges, **robot_options)`` -> (robot, port); every port must be done at teardown."""
    ports: list[ScriptedPort] = []

    def make(exchanges: list[Exchange], **options: Any) -> tuple[CrsA465, ScriptedPort]:
        port = ScriptedPort(exchanges)
        ports.append(port)
        options.setdefault("link", FAST_LINK)
        options.setdefault("shell", ShellProfile.system())
        options.setdefault("safety", SafetyLimits())
        return CrsA465(port, **options), port

    yield make
    for port in ports:
        port.assert_done()


@pytest.fixture
def make_twin() -> Iterator[Callable[..., ControllerTwin]]:
    """``make_twin(**settings)`` -> a started twin (100x faster than real, seeded); closed at teardown."""
    twins: list[ControllerTwin] = []

    def make(**settings: Any) -> ControllerTwin:
        settings.setdefault("time_scale", 100.0)
        settings.setdefault("seed", 1)
        twin = ControllerTwin(**settings).start()
        twins.append(twin)
        return twin

    yield make
    for twin in twins:
        twin.close()


@pytest.fixture
def robot_on() -> Iterator[Callable[..., CrsA465]]:
    """``robot_on(twin, **options)`` -> a connected driver on the twin's pty; closed at teardown."""
    robots: list[CrsA465] = []

    def make(twin: ControllerTwin, **options: Any) -> CrsA465:
        options.setdefault("link", FAST_LINK)
        if twin.settings.shell == "application":
            options.setdefault("shell", ShellProfile.application(twin.settings.app_name))
        robot = CrsA465(twin.port, **options)
        robots.append(robot)
        robot.connect()
        return robot

    yield make
    for robot in robots:
        robot.close()
