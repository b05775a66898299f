"""Teaching the cell (issue 23, item 1): the reference pose, each artifact's crossing, normal and square
turn, and the distance sensor's mount, computed from the station's own readings (the encoders' joints,
the measured crossing, the sensor) through an arm model (``_maths``, pure), read from the devices
(``_procedure``), and written into ``station.toml`` with its comments kept and the old file backed up
(``_writer``; the written line's comment and the answer's ``model`` say which model). ``station teach``
is the CLI.

The model (``_model``) is the nominal one until the arm is calibrated; then teach the artifacts again
through the calibrated arm (``station teach ... --calibration FILE``, or the API's
``{"calibration_session": id}``). Through the nominal model the arm's orientation error (its joints'
zero and twist errors, 0.10-0.15 deg on the simulated arm) is in every taught turn; through the
calibrated arm it is gone (0.02-0.07 deg on the simulated cells). A normal is read from the sensor at four
points around the crossing. Through the nominal model the camera is shifted 30 mm between them, and the
normal carries the model's local position error (0.008-0.085 deg on the simulated day one). Through a
calibrated arm only the wrist turns (joint 6), so that the beam circles the optical axis between the
grooves, and the normal carries only the orientation of the wrist's axis, which a calibration from
crossings pins: 0.007-0.024 deg on the simulated day one, where shifting the camera gave 0.012-0.116
(the calibration does not pin its position error's gradient; ``TeachRig.plane_samples``).
A crossing's position is always read through the nominal model, at the same pose and from
the same readings: it is what every plan moves through, and a calibration from crossings alone does not
hold it (it leaves the camera's tilt on the flange and its distance along the optical axis loose: read
through the calibrated arm the positions moved 2-3 mm on the simulated cells, through the nominal model
they stay within 0.1 mm). The re-taught normals and turns are in the calibrated model's base frame, which
its artifacts define (its base row, ``alpha0``, ``a0``, ``d1``, ``theta1_offset``, stays nominal:
``station/calibration/CALIBRATION.md``): the true frame moved by the arm's base-row errors (0.05 deg on
the simulated arm).
"""

from station.teach._maths import (
    LOOK_DOWN,
    Plane,
    SensorOffsetFit,
    TeachError,
    camera_ray,
    crossing_on_plane,
    fit_plane,
    fit_sensor_offset,
    normal_of_camera,
    pose_to_see,
    sensor_point,
    square_on,
    square_turn_deg,
    wrist_turns_deg,
)
from station.teach._model import (
    CalibrationRefusedError,
    CalibrationSessionInvalidError,
    TeachModel,
    model_from_file,
    model_from_result,
    model_from_session,
    nominal_model,
)
from station.teach._procedure import (
    SENSOR_HEIGHTS_MM,
    TaughtArtifact,
    TaughtReference,
    TeachRig,
    camera_intrinsics,
    rig_for,
    teach_artifact,
    teach_reference,
    teach_sensor_mount,
)
from station.teach._values import taught_values
from station.teach._writer import ConfigUpdate, set_artifact, set_reference, set_sensor_mount_z, update_config

__all__ = [
    "LOOK_DOWN",
    "SENSOR_HEIGHTS_MM",
    "CalibrationRefusedError",
    "CalibrationSessionInvalidError",
    "ConfigUpdate",
    "Plane",
    "SensorOffsetFit",
    "TaughtArtifact",
    "TaughtReference",
    "TeachError",
    "TeachModel",
    "TeachRig",
    "camera_intrinsics",
    "camera_ray",
    "crossing_on_plane",
    "fit_plane",
    "fit_sensor_offset",
    "model_from_file",
    "model_from_result",
    "model_from_session",
    "nominal_model",
    "normal_of_camera",
    "pose_to_see",
    "rig_for",
    "sensor_point",
    "set_artifact",
    "set_reference",
    "set_sensor_mount_z",
    "square_on",
    "square_turn_deg",
    "taught_values",
    "teach_artifact",
    "teach_reference",
    "teach_sensor_mount",
    "update_config",
    "wrist_turns_deg",
]
