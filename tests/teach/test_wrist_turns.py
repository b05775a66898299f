"""Reading a plane by turning the wrist (``station.teach.wrist_turns_deg``): the turns of joint 6 that
put the distance sensor's spot between the artifact's grooves, on each diagonal, whichever way the
grooves lie in the image and whichever way joint 6 turns the camera. Pure geometry on the nominal arm."""

from __future__ import annotations

import math

import numpy as np
import pytest

from station.kinematics import Kinematics, transform
from station.teach import wrist_turns_deg

POSE = (0.0, 30.0, 60.0, 0.0, 90.0, 0.0)  # the camera looking down over the table
CAMERA = Kinematics(tool=transform(np.eye(3), [0.0, 0.0, 120.0]))


def mount(x: float, y: float, tilt_deg: float = 0.0) -> np.ndarray:
    c, s = math.cos(math.radians(tilt_deg)), math.sin(math.radians(tilt_deg))
    return transform(np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]), [x, y, 0.0])


def spot_angle_deg(kinematics: Kinematics, q: np.ndarray, sensor: np.ndarray, start: np.ndarray) -> float:
    """Where the beam's spot (68 mm out) lies around the optical axis, in the start pose's image (deg)."""
    spot = kinematics.forward(q) @ sensor @ np.array([0.0, 0.0, 68.0, 1.0])
    seen = np.linalg.inv(kinematics.forward(start)) @ spot
    return math.degrees(math.atan2(float(seen[1]), float(seen[0])))


@pytest.mark.parametrize("groove_deg", [0.0, 12.5, -30.0, 44.0])
@pytest.mark.parametrize("flip", [False, True])
def test_every_turn_puts_the_spot_on_a_diagonal_between_the_grooves(groove_deg: float, flip: bool) -> None:
    # a camera mounted upside down on its bracket turns the other way in its image when joint 6 turns
    tool = transform(np.diag([1.0, -1.0, -1.0]) if flip else np.eye(3), [0.0, 0.0, 120.0])
    kinematics = Kinematics(tool=tool)
    start = np.array(POSE)
    if flip:
        start[4] = -90.0
    sensor = mount(30.0, 10.0)
    turns = wrist_turns_deg(kinematics, start, sensor, groove_deg)
    assert turns is not None
    assert [abs(t) for t in turns] == sorted(abs(t) for t in turns)  # nearest first
    assert abs(turns[0]) <= 45.0
    diagonals = set()
    for turn in turns[:4]:
        q = start.copy()
        q[5] += turn
        relative = (spot_angle_deg(kinematics, q, sensor, start) - groove_deg) % 90.0
        assert relative == pytest.approx(45.0, abs=0.01), (turn, relative)
        diagonals.add(round((spot_angle_deg(kinematics, q, sensor, start) - groove_deg) % 360.0))
    assert len(diagonals) == 4  # one reading on each diagonal: the circle all round


def test_a_beam_that_cannot_circle_the_wrist_axis_gives_no_turns() -> None:
    start = np.array(POSE)
    assert wrist_turns_deg(CAMERA, start, mount(0.0, 2.0), 0.0) is None  # on the axis
    assert wrist_turns_deg(CAMERA, start, mount(30.0, 0.0, tilt_deg=8.0), 0.0) is None  # not along it
    assert wrist_turns_deg(CAMERA, start, mount(30.0, 0.0, tilt_deg=3.0), 0.0) is not None
