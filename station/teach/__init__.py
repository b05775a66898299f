"""Teaching the cell (issue 23, item 1): the reference pose, each artifact's crossing, normal and square
turn, and the distance sensor's mount, computed from the station's own readings through its nominal
model (``_maths``, pure), read from the devices (``_procedure``), and written into ``station.toml``
with its comments kept and the old file backed up (``_writer``). ``station teach`` is the CLI.
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
    "ConfigUpdate",
    "Plane",
    "SensorOffsetFit",
    "TaughtArtifact",
    "TaughtReference",
    "TeachError",
    "TeachRig",
    "camera_intrinsics",
    "camera_ray",
    "crossing_on_plane",
    "fit_plane",
    "fit_sensor_offset",
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
]
