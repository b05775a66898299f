"""The ruler measurement's parameters: the ruler's description, the camera model and a few limits.

Names are matched case-insensitively by ``station measure --artifact ruler --set NAME=VALUE``; the
ruler itself comes from ``--ruler FILE`` (a ``RulerSpec`` as JSON), the design's ruler by default.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from station.vision._ruler_spec import RulerSpec


class RulerParams(BaseModel):
    """Parameters of one ruler measurement (units in each field's description)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    ruler: RulerSpec = Field(default_factory=RulerSpec, description="the ruler measured")
    bit_depth: int | None = Field(
        None,
        ge=8,
        le=16,
        description="significant bits of 16-bit images (8-16); None = auto (sBIT, data range)",
    )
    camera_matrix: list[list[float]] | None = Field(
        None, description="3x3 OpenCV camera matrix: undistort, and measure under the principal point"
    )
    dist_coeffs: list[float] | None = Field(
        None, description="OpenCV distortion coefficients (k1 k2 p1 p2 [k3 ...])"
    )
    min_periods: float = Field(
        5.0, ge=3, le=100, description="fewest graduation periods in view across the whole pattern"
    )
    window_periods: int = Field(
        3, ge=1, le=8, description="longest phase window along the ruler (periods): at least 3 per strip"
    )
    strip_px: float = Field(16.0, ge=4, le=200, description="width of a phase strip across the ruler (px)")
    margin_px: float = Field(
        3.0, ge=1, le=50, description="distance kept from the line tips and the code gap (px)"
    )
    max_tilt_deg: float = Field(
        5.0, gt=0, le=45, description="tilt of the ruler's plane the perspective terms allow (a loose prior)"
    )
    focal_px: float = Field(
        6800.0, gt=0, le=1e6, description="focal length (px) for that prior; the camera matrix's when given"
    )
    outlier_sigma: float = Field(
        3.0, gt=2, le=50, description="bins this many sigmas off the model are dropped"
    )
    min_contrast_dn: float = Field(
        10.0, gt=0, le=255, description="weakest graduation contrast accepted (DN)"
    )

    @field_validator("bit_depth", mode="before")
    @classmethod
    def _auto_bit_depth(cls, value: object) -> object:
        return None if isinstance(value, str) and value.strip().lower() in ("auto", "none") else value

    @model_validator(mode="after")
    def _check(self) -> RulerParams:
        if self.camera_matrix is not None:
            k = np.asarray(self.camera_matrix, dtype=float)
            if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0:
                raise ValueError("camera_matrix must be a 3x3 OpenCV camera matrix with positive fx, fy")
            if self.dist_coeffs is not None and len(self.dist_coeffs) not in (4, 5, 8, 12, 14):
                raise ValueError("dist_coeffs must have 4, 5, 8, 12 or 14 values (OpenCV's models)")
        elif self.dist_coeffs is not None:
            raise ValueError("dist_coeffs need a camera_matrix")
        return self

    def with_values(self, **changes: Any) -> RulerParams:
        """A validated copy with ``changes``."""
        return type(self).model_validate({**self.model_dump(), **changes})


def parse_ruler_assignments(assignments: list[str]) -> dict[str, str]:
    """``NAME=VALUE`` strings -> ``{field: value}`` for ``RulerParams`` (case-insensitive names).

    Raises ``ValueError`` naming the bad assignment and the known names.
    """
    fields = {name.lower(): name for name in RulerParams.model_fields if name not in ("ruler",)}
    out: dict[str, str] = {}
    for item in assignments:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"--set {item!r}: expected NAME=VALUE, e.g. --set min_periods=6")
        key = name.strip().lower()
        if key not in fields:
            raise ValueError(
                f"--set {name!r}: unknown ruler parameter; known: {', '.join(sorted(fields))} (the ruler "
                "itself: --ruler FILE)"
            )
        out[fields[key]] = value.strip()
    return out
