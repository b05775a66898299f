"""The rulers fixed in a station's cell (``[[calibration.rulers]]``, issue 22), as the calibration plan
reads them::

    [[calibration.rulers]]
    name = "table, along +y"
    origin_mm = [-500.0, -150.0, 328.9]   # graduation 0 on the ruler's axis, its top surface (base frame)
    direction = [0.0, 1.0, 0.0]            # increasing position along the ruler (+s)
    normal = [0.0, 0.0, 1.0]               # its top surface's upward normal (an angle block: tilted)

Taught like the crossed artifacts (with the nominal kinematics: within a millimetre or so is enough, the
identification fits each ruler's placement). The ruler itself (pitch, code, length) is
``station.vision.RulerSpec``'s (``station/vision/RULER.md``).
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field, model_validator

Vector = tuple[float, float, float]


def _unit(v: Vector, what: str) -> Vector:
    norm = math.sqrt(sum(c * c for c in v))
    if not all(math.isfinite(c) for c in v) or norm < 1e-9:
        raise ValueError(f"{what} must be a finite, non-zero vector, got {list(v)}")
    return (v[0] / norm, v[1] / norm, v[2] / norm)


class RulerConfig(BaseModel):
    """One ruler of the cell (see the module notes); lengths in mm, base frame."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    origin_mm: Vector = Field(description="graduation 0's point on the ruler's axis, on its top surface")
    direction: Vector = Field(description="the direction of increasing position along the ruler (+s)")
    normal: Vector = Field((0.0, 0.0, 1.0), description="the top surface's upward normal (default level)")
    name: str | None = Field(None, max_length=80, description="what the cell calls it")
    length_mm: float = Field(250.0, gt=0, le=2000, description="the graduated length")
    glass_width_mm: float = Field(
        30.0, gt=0, le=500, description="the substrate's width across the ruler (the sensor's beam reads it)"
    )

    @model_validator(mode="after")
    def _geometry(self) -> RulerConfig:
        if not all(math.isfinite(c) for c in self.origin_mm):
            raise ValueError(f"a ruler's origin_mm must be finite, got {list(self.origin_mm)}")
        s = _unit(self.direction, "a ruler's direction")
        n = _unit(self.normal, "a ruler's normal")
        if n[2] < 0.5:
            raise ValueError(f"a ruler's normal must point up, within 60 deg of the base's +z, got {list(n)}")
        if abs(sum(a * b for a, b in zip(s, n, strict=True))) > 0.02:
            raise ValueError(
                f"a ruler's direction {list(self.direction)} must lie in its surface, square to its normal "
                f"{list(self.normal)} (within 0.02)"
            )
        return self


__all__ = ["RulerConfig"]
