"""The station's scale calibration: the artifact's true groove width, estimated by a validation session.

The groove width is only known to +0/-0.002 in (up to 6 % of the nominal 0.794 mm), and every length the
station measures scales with it. A validation session estimates it from the micrometer table (the
similarity fit's scale) with its standard uncertainty, and stores it as a JSON file
``{"groove_width_mm", "u_mm", "session_id"}``; later sessions and ``station measure
--scale-calibration FILE`` measure with it and record which one they used
(``diagnostics.scale_calibration``).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from station._pydantic import problems as describe

FILE_NAME = "scale-calibration.json"


class ScaleCalibrationError(ValueError):
    """A scale calibration file is missing, unreadable or invalid (the message names the file)."""


class ScaleCalibration(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    groove_width_mm: float = Field(gt=0.05, lt=50.0)
    u_mm: float = Field(ge=0.0, lt=50.0)
    session_id: str | None = None

    def record(self, source: str | Path | None = None) -> dict[str, Any]:
        """What a measurement records under ``diagnostics.scale_calibration``."""
        out: dict[str, Any] = self.model_dump()
        if source is not None:
            out["file"] = str(source)
        return out


def load(path: str | Path) -> ScaleCalibration:
    p = Path(path)
    try:
        raw = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise ScaleCalibrationError(f"{p}: no such scale calibration file") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise ScaleCalibrationError(f"{p}: cannot read the scale calibration: {exc}") from exc
    except json.JSONDecodeError as exc:
        raise ScaleCalibrationError(f"{p}: not JSON: {exc}") from exc
    try:
        cal = ScaleCalibration.model_validate(raw)
    except ValidationError as exc:
        problems = describe(exc, "file")
        raise ScaleCalibrationError(f"{p}: not a scale calibration: {problems}") from exc
    if not (math.isfinite(cal.groove_width_mm) and math.isfinite(cal.u_mm)):
        raise ScaleCalibrationError(f"{p}: groove_width_mm and u_mm must be finite")
    return cal


def save(cal: ScaleCalibration, path: str | Path) -> Path:
    """Write atomically (temporary file, fsync, rename)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".scale-", dir=p.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(cal.model_dump(), f, indent=2)
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def station_file(data_dir: str | Path) -> Path:
    """Where a station keeps its current scale calibration."""
    return Path(data_dir) / FILE_NAME
