"""The simulated cell as a calibrated arm model sees it: truth for tests of teaching through a calibration.

A calibrated model keeps its base row nominal (``alpha0``, ``a0``, ``d1``, ``theta1_offset``: no pose set
identifies them, ``station/calibration/CALIBRATION.md``), so the true arm is ``G`` times the model for
every joint 1 angle: ``G = T01_true(0) T01_nominal(0)^-1``, a rigid motion of everything the model reads
(``station.calibration._truth``'s ``G``). The model's base frame is the world's moved by ``G^-1``: an
artifact taught through a calibrated model is compared with ``G^-1`` of its true pose, its upward normal
and its square turn (``sim.station.taught_turns_deg``'s convention) in that frame
(:func:`artifacts_in_model_frame`).

What the fit leaves weak moves the model's frame further (CALIBRATION.md's weak directions; a fit from
crossings alone leaves the camera's tilt on the flange and its distance along the optical axis loose:
on the small calibration of ``tests/teach/test_teach_calibrated.py`` 0.4 deg and 4 mm, with 0.7 deg and
3 mm sigmas): the orientations about the optical axis and the planes' normals stay within a few
hundredths of a degree of ``G^-1``'s, the crossings' positions do not (millimetres), so only the
normals and turns are compared in this frame.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from sim.world import World
from station.kinematics import A465_DH, JOINTS, LOOK_DOWN, Kinematics, square_on

__all__ = ["ModelFrameArtifact", "artifacts_in_model_frame", "model_frame"]

FloatArray = npt.NDArray[np.float64]
ModelFrameArtifact = tuple[tuple[float, float, float], tuple[float, float, float], float]
"""An artifact's crossing (mm), upward normal and square turn (deg) in a calibrated model's frame."""


def model_frame(world: World) -> FloatArray:
    """``G`` (4x4): the calibrated model's base frame in the world's (``true(q) = G @ model(q)``)."""
    zeros = np.zeros(JOINTS)
    true_row = Kinematics([world.true_dh[0], *A465_DH[1:]]).flange(zeros)
    nominal_row = Kinematics(A465_DH).flange(zeros)
    return np.asarray(true_row @ np.linalg.inv(nominal_row), dtype=np.float64)


def artifacts_in_model_frame(world: World) -> list[ModelFrameArtifact]:
    """Each artifact's true crossing, upward normal and square turn, seen from the calibrated model's
    base frame (``G^-1`` of the world's)."""
    Ginv = np.linalg.inv(model_frame(world))
    out: list[ModelFrameArtifact] = []
    for T in world.artifact_poses():
        P = Ginv @ T
        up = -P[:3, 2]
        u = (square_on(up) @ LOOK_DOWN).T @ P[:3, 0]
        position = (float(P[0, 3]), float(P[1, 3]), float(P[2, 3]))
        normal = (float(up[0]), float(up[1]), float(up[2]))
        out.append((position, normal, math.degrees(math.atan2(float(u[1]), float(u[0])))))
    return out
