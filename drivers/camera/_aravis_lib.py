"""Aravis itself, outside any one camera: loading it (PyGObject), listing the cameras it sees, and
turning an Aravis buffer into a checked image. ``drivers.camera.aravis`` re-exports every name.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from types import ModuleType
from typing import Any

from station.devices import DeviceConnectionError, FrameError, ImageArray

from ._frames import Layout, image_from_bytes

log = logging.getLogger(__name__)

ARAVIS_API = "0.8"
INSTALL_HINT = (
    "install Aravis and PyGObject: apt-get install gir1.2-aravis-0.8 (tools/apt-packages.txt) and "
    "pip install 'PyGObject<3.51' (the project's genicam extra); tools/setup.sh does both"
)
PIXEL_FORMAT_CODES = {"Mono8": 0x01080001, "Mono16": 0x01100007}
"""PFNC codes of the supported pixel formats, as buffers report them."""


def load_aravis() -> tuple[ModuleType, type[Exception]]:
    """Aravis and GLib.Error, or DeviceConnectionError saying what to install."""
    try:
        import gi

        gi.require_version("Aravis", ARAVIS_API)
        from gi.repository import Aravis, GLib
    except (ImportError, ValueError) as exc:
        raise DeviceConnectionError(f"Aravis {ARAVIS_API} is not available ({exc}); {INSTALL_HINT}") from exc
    return Aravis, GLib.Error


def aravis_available() -> bool:
    """Whether Aravis can be loaded here (for tests and diagnostics)."""
    try:
        load_aravis()
    except DeviceConnectionError:
        return False
    return True


@dataclass(frozen=True)
class CameraInfo:
    """A camera Aravis discovered."""

    id: str
    vendor: str
    model: str
    serial: str
    address: str
    protocol: str
    physical_id: str


def discover(*, include_fake: bool = False) -> list[CameraInfo]:
    """The cameras Aravis sees now (GigE Vision on every interface, USB3 Vision).

    ``include_fake`` also enables Aravis' in-process fake camera (``Fake_1``).
    """
    aravis, _ = load_aravis()
    if include_fake:
        aravis.enable_interface("Fake")
    aravis.update_device_list()
    found = [
        CameraInfo(
            id=aravis.get_device_id(i) or "",
            vendor=aravis.get_device_vendor(i) or "",
            model=aravis.get_device_model(i) or "",
            serial=aravis.get_device_serial_nbr(i) or "",
            address=aravis.get_device_address(i) or "",
            protocol=aravis.get_device_protocol(i) or "",
            physical_id=aravis.get_device_physical_id(i) or "",
        )
        for i in range(aravis.get_n_devices())
    ]
    log.debug("Aravis sees %d camera(s): %s", len(found), [c.id for c in found])
    return found


def image_from_buffer(buffer: Any, layout: Layout, *, aravis: ModuleType, source: str) -> ImageArray:
    """The image in an Aravis buffer, checked against what the camera was set to deliver.

    Raises FrameError for an incomplete frame (any status but SUCCESS), a buffer without an image, or
    a size, pixel format or byte count that differs from ``layout``.
    """
    status = buffer.get_status()
    if status != aravis.BufferStatus.SUCCESS:
        raise FrameError(
            f"{source}: incomplete frame ({status.value_nick}); on GigE check the link and packet size "
            "(jumbo frames, arv-tool-0.8), and that the host keeps up with the frame rate"
        )
    if buffer.get_payload_type() != aravis.BufferPayloadType.IMAGE:
        raise FrameError(f"{source}: the frame holds no image ({buffer.get_payload_type().value_nick})")
    code = int(buffer.get_image_pixel_format())
    size = (int(buffer.get_image_width()), int(buffer.get_image_height()))
    if code != PIXEL_FORMAT_CODES[layout.pixel_format] or size != (layout.width, layout.height):
        raise FrameError(
            f"{source}: the frame is {size[0]}x{size[1]} pixel format {code:#010x}, the camera was set "
            f"to {layout.describe()}; has something else changed its settings?"
        )
    return image_from_bytes(buffer.get_image_data(), layout, source=source)


__all__ = [
    "ARAVIS_API",
    "INSTALL_HINT",
    "PIXEL_FORMAT_CODES",
    "CameraInfo",
    "aravis_available",
    "discover",
    "image_from_buffer",
    "load_aravis",
]
