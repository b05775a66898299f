"""The simulated A465's kinematic (geometric) errors: the true DH table the sim world's arm is built to.

A real arm differs from its nominal DH table by machining and assembly tolerances; the controller does
not know by how much, so it reports WORLD values and plans moves with the nominal table while the arm's
links put the flange somewhere slightly different. Calibration (``station.calibration``) identifies
these errors from the station's relative measurements.

:func:`perturbed_dh` draws a true table from the nominal one, uniformly within
:class:`DHErrorBounds` (per row: ``a`` and ``d`` +/-0.5 mm, ``alpha`` +/-0.1 deg, the joint zero
+/-0.05 deg as a theta offset, and Hayati's ``beta`` +/-0.05 deg on the link between the nominally
parallel axes 2 and 3), deterministic per seed. Truth for tests and benchmarks only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from station.kinematics import A465_DH, DHRow

PARALLEL_LINK_ROW = 2
"""Index of the DH row between the A465's nominally parallel axes 2 and 3 (``a2``, ``beta2``)."""


@dataclass(frozen=True)
class DHErrorBounds:
    """Half-widths of the uniform kinematic errors (mm, deg)."""

    length_mm: float = 0.5
    twist_deg: float = 0.1
    zero_deg: float = 0.05
    parallel_tilt_deg: float = 0.05

    def __post_init__(self) -> None:
        for name in ("length_mm", "twist_deg", "zero_deg", "parallel_tilt_deg"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"DHErrorBounds.{name} must be finite and >= 0, got {value!r}")


def perturbed_dh(
    seed: int, nominal: Sequence[DHRow] = A465_DH, bounds: DHErrorBounds | None = None
) -> tuple[DHRow, ...]:
    """A true DH table: ``nominal`` plus uniform errors within ``bounds``, deterministic per ``seed``."""
    b = bounds or DHErrorBounds()
    rng = np.random.default_rng([0x4B1, seed])
    rows = []
    for i, r in enumerate(nominal):
        da, dd = rng.uniform(-b.length_mm, b.length_mm, 2)
        dalpha = rng.uniform(-b.twist_deg, b.twist_deg)
        dzero = rng.uniform(-b.zero_deg, b.zero_deg)
        dbeta = rng.uniform(-b.parallel_tilt_deg, b.parallel_tilt_deg) if i == PARALLEL_LINK_ROW else 0.0
        rows.append(
            DHRow(
                alpha_deg=r.alpha_deg + float(dalpha),
                a_mm=r.a_mm + float(da),
                d_mm=r.d_mm + float(dd),
                theta_offset_deg=r.theta_offset_deg + float(dzero),
                beta_deg=r.beta_deg + float(dbeta),
            )
        )
    return tuple(rows)


__all__ = ["PARALLEL_LINK_ROW", "DHErrorBounds", "perturbed_dh"]
