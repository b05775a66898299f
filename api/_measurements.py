"""Images measured by the service: an uploaded file (``POST /measure``), a frame from the camera with
the measurement drawn (the live view between sessions), and a session's latest stored capture with its
own measurement (the live view in a session). Routers get it as a FastAPI dependency."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from api._overlay import Picture, overlay_png
from station.batch import measure_loaded
from station.imageio import ImageLimits, decode_image
from station.plans import PlanError
from station.record import Record
from station.vision import MeasurementError, MeasureParams, measure
from station.worker import ConflictError


class Measurements:
    """``station_params``: the station's own measurement parameters (its configuration's, with its scale
    calibration's groove width); ``grab``: one frame from the camera (through the worker)."""

    def __init__(
        self, record: Record, station_params: Callable[[], MeasureParams], grab: Callable[[], Any]
    ) -> None:
        self.record = record
        self._station_params = station_params
        self._grab = grab

    def measure_image(
        self,
        data: bytes,
        params: Mapping[str, Any],
        *,
        name: str = "upload",
        limits: ImageLimits | None = None,
    ) -> dict[str, Any]:
        """The ``station measure --json`` object for an uploaded image (``ok`` false for a failed
        measurement). ImageFileError for a file that cannot be decoded; PlanError for bad parameters."""
        try:
            mp = MeasureParams.model_validate(dict(params))
        except ValueError as exc:
            raise PlanError(f"measurement parameters: {exc}") from exc
        return measure_loaded(name, decode_image(data, name=name, limits=limits), mp).to_json()

    def snapshot_png(self, *, overlay: bool = False) -> Picture:
        """One frame from the camera as PNG (optionally with the measurement drawn, or its refusal);
        ConflictError while a session owns the camera."""
        image = self._grab()
        result = self._measure_array(image) if overlay else None
        return Picture(overlay_png(image, result), result)

    def _measure_array(self, image: Any) -> dict[str, Any]:
        try:
            return measure(image, self._station_params()).to_json()
        except MeasurementError as exc:
            return {"ok": False, "error": exc.message, "code": exc.code}

    def latest_capture_png(self, session_id: str, *, overlay: bool = True) -> Picture:
        """The session's latest stored capture with its measurement drawn (the live view in a session);
        two rows read, however many the session holds."""
        row = self.record.get_session(session_id)
        cap = self.record.latest_capture(row.id)  # the newest stored: a resume's prelude is not last
        if cap is None:
            raise ConflictError(f"session {row.id} has no capture yet")
        image = self.record.load_image(cap)
        result = None
        if overlay:
            found = self.record.latest_measurement(row.id, cap.id)
            result = found.result if found is not None else None
        return Picture(overlay_png(image, result), result)
