"""A simulated station served with a lab's configuration file (``ServiceSettings(sim=True, config=F)``):
the sim's devices with F's taught values, which the teach routes rewrite. Shared by the jog and teach
tests, the page's teach test and the day-one test."""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from api import Access, ServiceSettings, StationService
from tests.api.conftest import TOKEN, Served, serve

LAB_CONFIG = """\
# the lab's station, as its drawing gives it: keep this comment
name = "lab"

[robot]
driver = "crs_a465"
options = {{ port = "/dev/ttyS0" }}   # the console port
reference_joints_deg = {reference}

[camera]
driver = "sim"
mount = {{ translation_mm = [0.0, 0.0, 120.0] }}   # the flange bracket's drawing: the pinhole 120 mm out

[distance_sensor]
driver = "keyence_il"
options = {{ port = "/dev/ttyUSB0" }}
mount = {{ translation_mm = [30.0, 0.0, {sensor_z}] }}   # from the bracket's drawing

[calibration]
# the artifacts as the drawing places them (a few millimetres off)
artifacts_mm = {artifacts}
artifact_names = {names}
artifact_normals = {normals}
artifact_turns_deg = {turns}
working_distance_mm = 68   # the lens's datasheet
pixel_mm = 0.01
"""


def lab_config(
    *,
    reference: list[float],
    artifacts: list[list[float]],
    normals: list[list[float]],
    turns: list[float],
    names: list[str],
    sensor_z: float = 2.0,
) -> str:
    """The lab's ``station.toml`` with these approximate values."""
    return LAB_CONFIG.format(
        reference=json.dumps(reference),
        artifacts=json.dumps(artifacts),
        normals=json.dumps(normals),
        turns=json.dumps(turns),
        names=json.dumps([str(n) for n in names]),
        sensor_z=sensor_z,
    )


@contextmanager
def served_with_config(path: Path, data: Path, **sim_options: Any) -> Iterator[Served]:
    """The simulated station served (on 127.0.0.1) with the configuration file at ``path``."""
    settings = ServiceSettings(sim=True, config=path, data=data, sim_options=sim_options)
    served = serve(StationService(settings), Access(TOKEN))
    try:
        yield served
    finally:
        served.stop()
