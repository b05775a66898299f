"""The station's device interfaces: what plans and the runner may ask of hardware.

Each interface is a small typed ``Protocol``; a real driver (``drivers/``) and its simulated twin
(``sim/``) are siblings that both satisfy it, and one parametrised contract suite runs against every
implementation. Units are mm and degrees at every interface (the X-Y table too: its operator prompt
shows inches). Errors are the exceptions below, each with a message that tells the operator what to do.
"""

from __future__ import annotations

from station.devices._camera import (
    PIXEL_FORMATS,
    Camera,
    CameraStatus,
    DeviceBusyError,
    ExposureAdjustable,
    Frame,
    FrameError,
    FrameRateAdjustable,
    GainAdjustable,
    ImageArray,
    InvalidSettingError,
    Roi,
    RoiSelectable,
    average_frames,
    grab_frames,
)
from station.devices._errors import (
    ControllerError,
    DeviceConnectionError,
    DeviceError,
    DeviceProtocolError,
    DeviceTimeoutError,
    MotionRejectedError,
    MotionStoppedError,
    NotSupportedError,
    StopLatchedError,
)
from station.devices._lifecycle import (
    Connectable,
    DeviceIdentity,
)
from station.devices._robot import (
    JOINT_COUNT,
    Joints6,
    Robot,
    RobotPosition,
    RobotStatus,
)
from station.devices._sensor import (
    DISTANCE_STATES,
    DistanceSensor,
    DistanceSensorStatus,
    OutOfRangeError,
    SensorAlarmError,
)
from station.devices._table import (
    OperatorCancelledError,
    TablePosition,
    XYTable,
)

__all__ = [
    "DISTANCE_STATES",
    "JOINT_COUNT",
    "PIXEL_FORMATS",
    "Camera",
    "CameraStatus",
    "Connectable",
    "ControllerError",
    "DeviceBusyError",
    "DeviceConnectionError",
    "DeviceError",
    "DeviceIdentity",
    "DeviceProtocolError",
    "DeviceTimeoutError",
    "DistanceSensor",
    "DistanceSensorStatus",
    "ExposureAdjustable",
    "Frame",
    "FrameError",
    "FrameRateAdjustable",
    "GainAdjustable",
    "ImageArray",
    "InvalidSettingError",
    "Joints6",
    "MotionRejectedError",
    "MotionStoppedError",
    "NotSupportedError",
    "OperatorCancelledError",
    "OutOfRangeError",
    "Robot",
    "RobotPosition",
    "RobotStatus",
    "Roi",
    "RoiSelectable",
    "SensorAlarmError",
    "StopLatchedError",
    "TablePosition",
    "XYTable",
    "average_frames",
    "grab_frames",
]
