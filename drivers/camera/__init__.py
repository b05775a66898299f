"""Camera drivers: a V4L2 frame grabber through OpenCV, and GenICam cameras through Aravis.

Both satisfy ``station.devices.Camera`` (registered as ``camera.v4l2`` and ``camera.aravis``).
Aravis is loaded only when a camera is opened, so this package imports without it.
"""

from .aravis import AravisCamera, CameraInfo, aravis_available, discover
from .v4l2 import V4L2Camera

__all__ = ["AravisCamera", "CameraInfo", "V4L2Camera", "aravis_available", "discover"]
