"""The ``sweep`` kind's results (um): one trial per parameter set of the grid, and the best."""

from __future__ import annotations

from typing import Any

from pydantic import Field

from station.plans._results import ResultsModel


class SweepTrial(ResultsModel):
    """One trial: ``mean_um`` / ``max_um`` after the rigid fit (raw), ``parallelogram_*_um`` after the
    affine fit (Table 1's MaxE / MeanE) when the trial recorded them."""

    number: int
    overrides: dict[str, Any] = Field(default_factory=dict)
    mean_um: float | None = None
    max_um: float | None = None
    parallelogram_mean_um: float | None = None
    parallelogram_max_um: float | None = None
    error: str | None = None


class SweepResults(ResultsModel):
    trials: list[SweepTrial]
    best: int | None = None
    source_session: str | int | None = None
