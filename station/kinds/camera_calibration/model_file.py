"""Where a passed camera calibration writes the station's camera model, the one it replaces kept.

The model goes to the configured ``[camera] camera_model`` path when the configuration names a JSON file,
else to ``camera-model.json`` in the data directory (:data:`DEFAULT_NAME`; the configuration must then
name it for sessions to use it: the results say so). Nothing is lost: before a model is replaced, the old
file is copied to ``DATA/camera-model-history/NNNN<suffix>`` (numbered, never overwritten), as the scale
calibration keeps its history (``station.scale_calibration``).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from station.camera_model import CameraIntrinsics, CameraModelError, write_camera_model

__all__ = ["DEFAULT_NAME", "HISTORY_DIR", "ModelWritten", "model_path", "write_with_history"]

DEFAULT_NAME = "camera-model.json"
HISTORY_DIR = "camera-model-history"


@dataclass(frozen=True)
class ModelWritten:
    """``path``: the model written; ``previous``: the copy of the one it replaced (None: there was none);
    ``configured``: whether the configuration names ``path`` (else it must be told to)."""

    path: Path
    previous: Path | None
    configured: bool


def model_path(configured: str | Path | None, data_dir: str | Path) -> tuple[Path, bool]:
    """The file to write: the configured JSON model, else ``DATA/camera-model.json`` (and whether it is
    the configured one). A configured YAML/XML model is not overwritten: the new one goes to the data
    directory beside it."""
    if configured is not None and Path(configured).suffix.lower() == ".json":
        return Path(configured), True
    return Path(data_dir) / DEFAULT_NAME, False


def _keep(old: Path, data_dir: Path) -> Path:
    folder = data_dir / HISTORY_DIR
    folder.mkdir(parents=True, exist_ok=True)
    taken = [int(p.stem) for p in folder.iterdir() if p.stem.isdigit()]
    target = folder / f"{max(taken, default=0) + 1:04d}{old.suffix}"
    if target.exists():
        raise CameraModelError(f"{target} exists: the camera model history is never overwritten")
    shutil.copy2(old, target)
    return target


def write_with_history(
    model: CameraIntrinsics, configured: str | Path | None, data_dir: str | Path
) -> ModelWritten:
    """Write ``model`` where :func:`model_path` says, the file it replaces copied to the history first."""
    data = Path(data_dir)
    path, is_configured = model_path(configured, data)
    previous = _keep(path, data) if path.exists() else None
    write_camera_model(model, path)
    return ModelWritten(path, previous, is_configured)
