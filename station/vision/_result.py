"""The measurement result: centre, corners, lines and the diagnostics that explain them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from station.vision._edges import EDGES, Edge
from station.vision._params import MeasureParams

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class EdgeFit:
    """One edge: its line ``a*x + b*y = c`` (a^2 + b^2 = 1, px) and how it was found.

    ``segmented``: pixels the segmentation gave; ``used``: points in the final fit; ``removed``:
    outliers dropped; ``rms_px``: rms perpendicular residual of the used points; ``points``: the
    sub-pixel points used, (used, 2) ``(x, y)`` px.
    """

    name: Edge
    line: tuple[float, float, float]
    segmented: int
    used: int
    removed: int
    rms_px: float
    points: FloatArray = field(repr=False, compare=False)


@dataclass(frozen=True)
class Measurement:
    """Where the artifact's crossing is in one image.

    ``center_px``: image of the artifact's centre (crossing of the quadrilateral's diagonals), px, 0-based,
    x right, y down. ``center_mm``: the crossing relative to the image origin pixel (0, 0), in mm, in the
    artifact's axes (groove directions nearest image x and y, same handedness). ``corners_px``: (4, 2),
    in the order mapped to (0, 0), (w, 0), (w, w), (0, w): top-left, top-right, bottom-right,
    bottom-left. ``lines``: (4, 3) normal-form lines in the order top, bottom, left, right.
    ``homography``: 3x3 image px -> groove-width square mm. ``rotation_deg``: mean in-plane rotation of
    the grooves (positive turns image +x toward +y). ``groove_width_px``: (horizontal groove,
    vertical groove) at the crossing.
    """

    center_px: tuple[float, float]
    center_mm: tuple[float, float]
    corners_px: FloatArray
    lines: FloatArray
    homography: FloatArray
    edges: dict[Edge, EdgeFit]
    rotation_deg: float
    groove_width_px: tuple[float, float]
    params: MeasureParams
    extra: dict[str, Any] = field(default_factory=dict)

    def diagnostics(self) -> dict[str, Any]:
        """JSON-ready diagnostics: per-edge counts and residuals, rotation, widths, parameters."""
        return {
            "mode": self.params.mode,
            "edges": {
                name: {
                    "segmented": e.segmented,
                    "used": e.used,
                    "removed": e.removed,
                    "rms_px": round(e.rms_px, 6),
                }
                for name, e in ((n, self.edges[n]) for n in EDGES)
            },
            "rotation_deg": round(self.rotation_deg, 6),
            "groove_width_px": [round(v, 6) for v in self.groove_width_px],
            "line_order": list(EDGES),
            "corner_order": ["top-left", "top-right", "bottom-right", "bottom-left"],
            **self.extra,
            "params": self.params.model_dump(),
        }

    def to_json(self) -> dict[str, Any]:
        """The ``station measure --json`` object (without ``file``)."""
        return {
            "ok": True,
            "center_px": [float(v) for v in self.center_px],
            "center_mm": [float(v) for v in self.center_mm],
            "corners_px": self.corners_px.tolist(),
            "lines": self.lines.tolist(),
            "diagnostics": self.diagnostics(),
        }
