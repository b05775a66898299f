"""Camera drivers: a V4L2 frame grabber through OpenCV, and GenICam cameras through Aravis.

Both satisfy ``station.devices.Camera`` (registered as ``camera.v4l2`` and ``camera.aravis``).
Aravis is loaded only when a camera is opened, so this package imports without it.
"""

import functools
from collections.abc import Callable
from typing import ParamSpec

from station.devices import Camera

from .aravis import AravisCamera, CameraInfo, aravis_available, discover
from .v4l2 import V4L2Camera

P = ParamSpec("P")


def _camera_factory(cls: Callable[P, Camera]) -> Callable[P, Camera]:
    """A registered factory: builds the camera unconnected; mypy checks the class is a ``Camera``."""

    @functools.wraps(cls)
    def build(*args: P.args, **kwargs: P.kwargs) -> Camera:
        return cls(*args, **kwargs)

    return build


open_v4l2_camera = _camera_factory(V4L2Camera)
open_aravis_camera = _camera_factory(AravisCamera)

__all__ = [
    "AravisCamera",
    "CameraInfo",
    "V4L2Camera",
    "aravis_available",
    "discover",
    "open_aravis_camera",
    "open_v4l2_camera",
]
