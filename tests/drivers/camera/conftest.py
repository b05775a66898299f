"""Camera test fixtures: Aravis availability (skip locally, fail under CI), the GigE Vision simulator."""

from __future__ import annotations

import shutil
from collections.abc import Iterator

import pytest

from drivers.camera.aravis import INSTALL_HINT, aravis_available
from tests.conftest import needs_system

from .gv_simulator import PROGRAM, GvSimulator


def require_aravis() -> None:
    needs_system("Aravis 0.8 through PyGObject", aravis_available(), INSTALL_HINT)


def require_gv_simulator() -> None:
    require_aravis()
    needs_system(PROGRAM, shutil.which(PROGRAM) is not None, "Debian package aravis-tools")


@pytest.fixture(scope="session")
def gv_simulator() -> Iterator[GvSimulator]:
    """This worker's handle on the shared simulator; stops the one it started at the end."""
    simulator = GvSimulator()
    yield simulator
    simulator.stop()


@pytest.fixture
def gv_sim_pid(gv_simulator: GvSimulator) -> Iterator[int]:
    """The simulator, held exclusively by this test (cameras opened in the test close before release)."""
    require_gv_simulator()
    with gv_simulator.exclusive() as pid:
        yield pid
