"""The measurement parameters: one pydantic model, named as the seed names them.

Seed: Fratpietro & Hayes, section 3.2 (FILTER, TESTHEIGHT, TESTWIDTH, SKIP, threshold) and section 4
(Table 1). Paper mode's defaults are Table 1's trial 7: no filter, SKIP 1, TESTWIDTH 5, TESTHEIGHT 5.
Precise mode (the default) has its own fields, marked "precise:"; each mode ignores the other's.
Names are matched case-insensitively by ``station measure --set NAME=VALUE``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

Mode = Literal["paper", "precise"]
FilterKind = Literal["none", "mean", "gauss"]

#: Nominal groove width: 0.794 mm (1/32 in; the paper's label "1/16 in" is wrong).
NOMINAL_GROOVE_WIDTH_MM = 25.4 / 32
#: The densest printed row of the seed's 7x7 mask (2 4 8 16 8 4 2) halves per pixel: sigma = 1/sqrt(2 ln 2).
SEED_GAUSS_SIGMA_PX = 1.0 / math.sqrt(2.0 * math.log(2.0))


class MeasureParams(BaseModel):
    """Parameters of one measurement (units in each field's description)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    mode: Mode = Field("precise", description="algorithm: 'precise' (default) or 'paper' (the seed's)")
    filter: FilterKind = Field("none", description="FILTER, seed 3.2.1: none | mean (3x3) | gauss (7x7)")
    gauss_sigma: float = Field(
        SEED_GAUSS_SIGMA_PX, gt=0, le=3, description="sigma of the 7x7 Gaussian of eq. 2 (px)"
    )
    threshold: float = Field(0.30, gt=0, lt=1, description="fraction of the maximum response kept, 3.2.3")
    skip: int = Field(1, ge=1, le=100, description="SKIP: columns between scanned columns, 3.2.4")
    testwidth: int = Field(5, ge=1, le=100, description="TESTWIDTH: offset of columns E and F (px), eq. 6")
    testheight: int = Field(5, ge=1, le=100, description="TESTHEIGHT: half height of column A (px), eq. 5")
    backoff: int | None = Field(
        None, ge=0, le=200, description="rows the TestBox moves back up after a hit (px); None = TESTHEIGHT"
    )
    corr_tol: float = Field(
        0.0, ge=0, le=1, description="recursive fit: remove points while |r| is below this (0 = off)"
    )
    change_tol: float = Field(
        1e-4, ge=0, le=1, description="recursive fit: remove points while removal changes |r| by more"
    )
    max_removals: int = Field(50, ge=0, le=10_000, description="recursive fit: most points removed, 3.2.4")
    groove_width_mm: float = Field(
        NOMINAL_GROOVE_WIDTH_MM, ge=0.05, le=50, description="groove width w, the square's side (mm), 3.2.5"
    )
    bit_depth: int | None = Field(
        None,
        ge=8,
        le=16,
        description="significant bits of 16-bit images (8-16); None = auto: PNG's sBIT, else data range",
    )
    min_edge_points: int = Field(8, ge=3, le=100_000, description="fewest points that make an edge")
    max_residual_px: float | None = Field(
        None,
        gt=0,
        le=1000,
        description="largest rms distance of an edge's points (px); None: paper 2.0, precise 0.5",
    )
    max_rotation_deg: float | None = Field(
        None, gt=0, le=45, description="largest in-plane rotation accepted (deg); None: paper 30, precise 40"
    )
    # precise mode (issue 3): band-limited sub-pixel edge points and robust orthogonal fits
    window_px: int | None = Field(
        None, ge=2, le=20, description="precise: half-width of the edge profile window (px); None = auto"
    )
    window_sigmas: float = Field(
        2.5, ge=1.5, le=6, description="precise: auto window half-width in line-spread sigmas (+1 px)"
    )
    impulse_dn: float = Field(
        25.0, gt=0, le=255, description="precise: a profile sample this far from its 3-median is an impulse"
    )
    flat_field: bool = Field(
        True, description="precise: divide edge profiles by the illumination fitted over the lands"
    )
    profile_step: int = Field(
        1, ge=1, le=16, description="precise: columns (rows) between edge profiles in the last pass"
    )
    passes: int = Field(2, ge=2, le=6, description="precise: re-centring passes (the last one is kept)")
    corner_margin_px: float = Field(
        14.0, ge=0, le=200, description="precise: edge excluded this far beyond the perpendicular groove (px)"
    )
    outlier_sigma: float = Field(3.5, gt=1, le=20, description="precise: inlier band, robust sigmas")
    min_contrast_dn: float = Field(
        10.0, gt=0, le=255, description="precise: weakest edge accepted, median step across it (DN)"
    )
    min_contrast_fraction: float = Field(
        0.5, gt=0, lt=1, description="precise: weakest profile kept, as a fraction of the median contrast"
    )
    camera_matrix: list[list[float]] | None = Field(
        None, description="precise: 3x3 OpenCV camera matrix for lens-distortion correction (off if None)"
    )
    dist_coeffs: list[float] | None = Field(
        None, description="precise: OpenCV distortion coefficients (k1 k2 p1 p2 [k3 ...])"
    )

    @field_validator("bit_depth", mode="before")
    @classmethod
    def _auto_bit_depth(cls, value: object) -> object:
        return None if isinstance(value, str) and value.strip().lower() in ("auto", "none") else value

    @model_validator(mode="after")
    def _check(self) -> MeasureParams:
        if self.filter == "gauss" and self.gauss_sigma > 7 / 3:
            raise ValueError(f"gauss_sigma {self.gauss_sigma} px is too wide for a 7x7 mask (at most 2.33)")
        if self.camera_matrix is not None:
            k = np.asarray(self.camera_matrix, dtype=float)
            if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0:
                raise ValueError("camera_matrix must be a 3x3 OpenCV camera matrix with positive fx, fy")
            if self.dist_coeffs is not None and len(self.dist_coeffs) not in (4, 5, 8, 12, 14):
                raise ValueError("dist_coeffs must have 4, 5, 8, 12 or 14 values (OpenCV's models)")
        elif self.dist_coeffs is not None:
            raise ValueError("dist_coeffs need a camera_matrix")
        return self

    @property
    def rotation_limit_deg(self) -> float:
        if self.max_rotation_deg is not None:
            return self.max_rotation_deg
        return 30.0 if self.mode == "paper" else 40.0

    @property
    def residual_limit_px(self) -> float:
        if self.max_residual_px is not None:
            return self.max_residual_px
        return 2.0 if self.mode == "paper" else 0.5

    @property
    def backoff_rows(self) -> int:
        return self.testheight if self.backoff is None else self.backoff

    @classmethod
    def for_mode(cls, mode: Mode, **overrides: Any) -> MeasureParams:
        """Defaults of ``mode`` (paper: Table 1, trial 7) with ``overrides`` applied and validated."""
        return cls.model_validate({"mode": mode, **overrides})

    def with_values(self, **changes: Any) -> MeasureParams:
        """A validated copy with ``changes``."""
        return type(self).model_validate({**self.model_dump(), **changes})


def field_name(name: str, *, option: str = "--set") -> str:
    """The parameter model's field that ``name`` names, case-insensitively (``TESTWIDTH`` ->
    ``testwidth``): parameter names are case-insensitive wherever they are given (``--set``, ``--grid``,
    a sweep's ``grid``). Raises ``ValueError`` naming ``option``, the name and the known names."""
    fields = {f.lower(): f for f in MeasureParams.model_fields}
    key = name.strip().lower()
    if key not in fields:
        raise ValueError(f"{option} {name!r}: unknown parameter; known: {', '.join(sorted(fields))}")
    return fields[key]


def field_names(values: Mapping[str, Any], *, option: str = "--set") -> dict[str, Any]:
    """``values`` keyed by the parameter model's field names, matched case-insensitively (the one rule
    for every place names are given: ``--set``, a session's ``set``, ``POST /measure``'s query); raises
    ``ValueError`` naming ``option``, the unknown name and the known names."""
    return {field_name(k, option=option): v for k, v in values.items()}


def parse_assignments(assignments: list[str]) -> dict[str, str]:
    """Parse ``NAME=VALUE`` strings into a dict keyed by the model's field names (case-insensitive).

    Raises ``ValueError`` naming the bad assignment and the known names.
    """
    out: dict[str, str] = {}
    for item in assignments:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"--set {item!r}: expected NAME=VALUE, e.g. --set TESTWIDTH=5")
        out[field_name(name)] = value.strip()
    return out


def allowed_range(name: str) -> str:
    """The allowed values of a parameter as text ('0 < threshold < 1', 'filter: none, mean, gauss')."""
    info = MeasureParams.model_fields[name]
    low = high = ""
    for bound in info.metadata:
        for attr, text in (("gt", "<"), ("ge", "<=")):
            if getattr(bound, attr, None) is not None:
                low = f"{getattr(bound, attr):g} {text} "
        for attr, text in (("lt", "<"), ("le", "<=")):
            if getattr(bound, attr, None) is not None:
                high = f" {text} {getattr(bound, attr):g}"
    if low or high:
        optional = " (or auto)" if info.default is None else ""
        return f"{low}{name}{high}, finite{optional}"
    choices = getattr(info.annotation, "__args__", ())
    if choices and all(isinstance(c, str) for c in choices):
        return f"{name}: one of {', '.join(choices)}"
    return f"{name}: see station/vision/_params.py"
