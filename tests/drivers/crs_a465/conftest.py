"""Fixtures: controller twins on real ptys (both motion modes), and drivers connected to them.

Scripted exchanges use ``fakes.scripted_robot`` (a context manager: the verdict is in the test body).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from drivers.crs_a465 import CrsA465, LinkSettings, MotionSettings, ShellProfile
from sim.controller import ControllerTwin

# Short timeouts: a dropped reply costs a fraction of a second, not the real 3 s.
FAST_LINK = LinkSettings(reply_timeout_s=0.3, home_timeout_s=2.0, resync_quiet_s=0.02)
# The twin runs 100x faster than real: poll often, short margins.
TWIN_MOTION = MotionSettings(deadline_margin_s=1.0, stall_timeout_s=1.0, poll_interval_s=0.005)

MODES = ("firmware", "blocking")
"""The twin's two motion modes: the firmware's (prompt at once, the arm moves on) and the older blocking."""


@pytest.fixture(params=MODES)
def mode(request: pytest.FixtureRequest) -> str:
    """Run a contract test once per motion mode of the twin."""
    return str(request.param)


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
        options.setdefault("motion", TWIN_MOTION)
        if twin.settings.shell == "application":
            options.setdefault("shell", ShellProfile.application(twin.settings.app_name))
        robot = CrsA465(twin.port, **options)
        robots.append(robot)
        robot.connect()
        return robot

    yield make
    for robot in robots:
        robot.close()
