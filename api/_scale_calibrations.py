"""The station's scale calibration as the service serves it: its status, history and the revert, in the
record's data directory (``station.scale_calibration``); routers get it as a FastAPI dependency and never
reach into the record."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from station import scale_calibration as scal
from station.record import lock_holder
from station.worker import ConflictError, RunnerStatus


class ScaleCalibrations:
    """``data_dir``: the record's; ``running``: the service's running session, if any."""

    def __init__(self, data_dir: Path, running: Callable[[], RunnerStatus | None]) -> None:
        self._data = data_dir
        self._running = running

    def status(self) -> dict[str, Any]:
        return scal.status(self._data)

    def history(self) -> list[dict[str, Any]]:
        return scal.history_json(self._data)

    def revert(self) -> dict[str, Any]:
        """Back to the previous calibration; ConflictError while a session runs (here or in another
        process holding the station)."""
        running = self._running()
        holder = lock_holder(self._data)
        if running is not None or holder is not None:
            sid = running.session_id if running is not None else (holder or {}).get("session_id")
            raise ConflictError(f"session {sid} is running; revert the scale calibration once it has ended")
        entry = scal.revert(self._data)
        return {"entry": entry.model_dump(mode="json"), **scal.status(self._data)}
