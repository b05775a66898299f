"""The arm model teaching reads through: the nominal one (the arm's nominal kinematics with the camera's
mounting as its tool), or, once the arm is calibrated, the calibrated one.

Teaching through the nominal model puts the arm's orientation error (its joint zeros' and twists'
errors, about 0.1 deg on the simulated arm) into the taught normals and turns whole; the calibrated
model removes it. A calibrated model comes from a file ``station calibrate SESSION --out FILE`` wrote
(:func:`model_from_file`, ``station teach ... --calibration FILE``) or from a calibration session on
record (:func:`model_from_session`, the API's ``{"calibration_session": id}``), which must have
succeeded with its checks passed, on this station, with the controller the arm has now.

The calibrated model's base frame is the one its artifacts define: its base row (``alpha0``, ``a0``,
``d1``, ``theta1_offset``) stays nominal (no pose set identifies it), so the true arm's base-row errors
become a rigid motion of everything it reads (``station/calibration/CALIBRATION.md``). Values taught
through it are in that frame: the frame the calibrated arm moves in, which is the one the next
calibration and every compensated move (``move-camera --calibration``) use.

``TeachModel.source`` says which model a taught value was read through; it is recorded with it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from station.calibration import CalibrationError, CalibrationResult
from station.kinematics import Kinematics
from station.selftest_status import controller_key
from station.teach._maths import TeachError

__all__ = [
    "CALIBRATION_KIND",
    "CalibrationRefusedError",
    "CalibrationSessionInvalidError",
    "TeachModel",
    "model_from_file",
    "model_from_result",
    "model_from_session",
    "nominal_model",
]

CALIBRATION_KIND = "calibration"
RUN_ONE = "run the arm's calibration (station run calibration, or the page's Sessions panel) and name it"


class CalibrationSessionInvalidError(TeachError):
    """The calibration session named is not one (no such session, or one of another kind)."""


class CalibrationRefusedError(TeachError):
    """The calibration named cannot be taught through (it did not succeed, a check failed, another
    station, controller or camera mount); the message says what to do."""


@dataclass(frozen=True)
class TeachModel:
    """The kinematics teaching reads and moves through and where it comes from (``source``: ``{"model":
    "nominal"}`` or ``{"model": "calibrated", "created", and "calibration_session" or
    "calibration_file"}``)."""

    kinematics: Kinematics
    source: dict[str, Any] = field(default_factory=lambda: {"model": "nominal"})

    @property
    def calibrated(self) -> bool:
        return bool(self.source.get("model") == "calibrated")

    def describe(self) -> str:
        """A few words for the configuration file's comment: ``the nominal arm model``, ``calibration
        session ID`` or ``calibration file F``."""
        if not self.calibrated:
            return "the nominal arm model"
        if "calibration_session" in self.source:
            return f"calibration session {self.source['calibration_session']}"
        return f"calibration file {Path(str(self.source.get('calibration_file'))).name}"


def nominal_model(camera_mount: np.ndarray) -> TeachModel:
    """The nominal arm with the camera's mounting (4x4, flange frame) as its tool."""
    return TeachModel(Kinematics(tool=np.asarray(camera_mount, dtype=float)))


def model_from_result(
    result: CalibrationResult, camera_mount: np.ndarray, source: Mapping[str, Any]
) -> TeachModel:
    """The calibrated arm of ``result``, refused when it was identified with another camera mounting than
    the station's (``camera_mount``, 4x4): its tool is then another camera's."""
    if not np.allclose(np.asarray(result.nominal_tool, dtype=float), camera_mount, atol=1e-6):
        raise CalibrationRefusedError(
            "this calibration was identified with another camera mounting than the station's ([camera]"
            f" mount): {RUN_ONE} again with the camera as it is mounted now"
        )
    return TeachModel(result.kinematics(), {"model": "calibrated", **dict(source), "created": result.created})


def model_from_file(path: str | Path, camera_mount: np.ndarray) -> TeachModel:
    """The calibrated arm of a file ``station calibrate SESSION --out FILE`` wrote."""
    try:
        result = CalibrationResult.load(path)
    except CalibrationError as exc:
        raise CalibrationRefusedError(
            f"{exc}; write the file with station calibrate SESSION --out FILE"
        ) from exc
    return model_from_result(result, camera_mount, {"calibration_file": str(path)})


def model_from_session(
    session: Any,
    *,
    station: str,
    robot_identity: Mapping[str, Any] | None,
    session_identity: Mapping[str, Any] | None,
    camera_mount: np.ndarray,
) -> TeachModel:
    """The calibrated arm of a stored calibration session (a ``station.record`` session row: ``id``,
    ``kind``, ``state``, ``results``, ``station``), refused unless it is a calibration session of
    ``station`` that succeeded with every check of severity ``fail`` passed, run with the controller
    (``session_identity``: the robot's identity it ran with) that ``robot_identity`` (the arm's now)
    names, and with the camera mounted as ``camera_mount``."""
    sid = str(session.id)
    if session.kind != CALIBRATION_KIND:
        raise CalibrationSessionInvalidError(
            f"session {sid} is a {session.kind} session, not a calibration: {RUN_ONE}"
        )
    if session.station != station:
        raise CalibrationRefusedError(
            f"calibration session {sid} is station {session.station!r}'s, not this station's"
            f" ({station!r}): {RUN_ONE}"
        )
    if session.state != "succeeded" or not isinstance(session.results, Mapping):
        raise CalibrationRefusedError(
            f"calibration session {sid} is {session.state}, not succeeded: teach through one that"
            f" succeeded, or {RUN_ONE}"
        )
    failed = [
        str(c.get("name"))
        for c in session.results.get("checks", [])
        if isinstance(c, Mapping) and c.get("severity") == "fail" and not c.get("passed")
    ]
    if failed:
        raise CalibrationRefusedError(
            f"calibration session {sid} failed its checks ({', '.join(failed)}): {RUN_ONE}"
        )
    mine, theirs = controller_key(robot_identity), controller_key(session_identity)
    if mine is None or theirs != mine:
        raise CalibrationRefusedError(
            f"calibration session {sid} ran with another controller ({theirs}) than the arm has now"
            f" ({mine}): {RUN_ONE}"
        )
    document = session.results.get("calibration")
    if not isinstance(document, Mapping):
        raise CalibrationRefusedError(f"calibration session {sid} holds no calibrated arm: {RUN_ONE}")
    try:
        result = CalibrationResult.model_validate(dict(document))
    except ValueError as exc:
        raise CalibrationRefusedError(
            f"calibration session {sid}'s calibrated arm is not one this software reads ({exc}): re-run"
            f" its identification (station calibrate {sid}) or {RUN_ONE}"
        ) from exc
    return model_from_result(result, camera_mount, {"calibration_session": sid})
