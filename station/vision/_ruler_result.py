"""The ruler measurement's result: where along the ruler, how far off its axis, at what angle.

``position_mm``/``offset_mm``: the ruler coordinates ``(s, t)`` of the point on the ruler's plane
under the reference pixel (the image's origin pixel (0, 0), or the principal point with a camera
model): ``s`` from graduation 0 along the ruler, ``t`` across it from its axis (+90 deg from ``s``,
the image's handedness). Moving the ruler by +d along itself moves ``position_mm`` by -d.
``angle_deg``: the image direction of the ruler's axis toward increasing ``s``, degrees, positive
turning image +x toward +y.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from station.vision._ruler_code import CodeReading
from station.vision._ruler_frame import RulerFrame
from station.vision._ruler_params import RulerParams

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class RulerMeasurement:
    """One ruler measurement (module docstring); ``frame`` maps image px to the ruler in periods
    with ``s`` counted from graduation ``code.graduation``."""

    position_mm: float
    offset_mm: float
    angle_deg: float
    reference_px: tuple[float, float]
    frame: RulerFrame
    code: CodeReading
    params: RulerParams
    extra: dict[str, Any] = field(default_factory=dict)

    def to_ruler_mm(self, x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Ruler ``(s, t)`` in mm under image points (in the coordinates measured: undistorted px
        with a camera model)."""
        s, t = self.frame.map(x, y)
        pitch = self.params.ruler.pitch_mm
        return (s + self.code.graduation) * pitch, t * pitch

    def diagnostics(self) -> dict[str, Any]:
        """JSON-ready diagnostics: the fit's quality, the evidence, the parameters."""
        return {
            "reference_px": [float(v) for v in self.reference_px],
            **self.extra,
            "ruler": self.params.ruler.name,
            "params": self.params.model_dump(exclude={"ruler"}),
        }

    def to_json(self) -> dict[str, Any]:
        """The ``station measure --artifact ruler --json`` object (without ``file``)."""
        return {
            "ok": True,
            "artifact": "ruler",
            "position_mm": float(self.position_mm),
            "offset_mm": float(self.offset_mm),
            "angle_deg": float(self.angle_deg),
            "code": {
                "first_cell": self.code.first_cell,
                "bits": self.code.bits,
                "read": self.code.read,
                "disagreements": self.code.disagreements,
                "margin": self.code.margin,
            },
            "diagnostics": self.diagnostics(),
        }
