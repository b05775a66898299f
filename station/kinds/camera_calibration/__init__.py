"""The ``camera-calibration`` session kind (issue 23, item 2): the camera's intrinsics from views of the
standard target on the X-Y table (``plan``), its typed results (``results``), how they are shown
(``present``) and the camera model file it writes with its history (``model_file``)."""

from station.kinds.camera_calibration import present
from station.kinds.camera_calibration.plan import CAMERA_CALIBRATION
from station.kinds.camera_calibration.results import CameraCalibrationResults
from station.plans._kind import Kind

KIND = Kind(
    plan=CAMERA_CALIBRATION,
    results=CameraCalibrationResults,
    title="Camera calibration",
    summary=present.summary,
    rows=present.rows,
)

__all__ = ["KIND"]
