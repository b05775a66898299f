"""The ``sweep`` kind's results (um): one trial per parameter set of the grid, and the best; over an
archive selection, each trial's figures over every session and per session."""

from __future__ import annotations

from typing import Any

from pydantic import Field

from station.plans._results import ResultsModel


class SweepSessionTrial(ResultsModel):
    """One trial on one session of a selection: its figures there and the positions they compare."""

    session: str
    positions: int = 0
    mean_um: float | None = None
    max_um: float | None = None
    parallelogram_mean_um: float | None = None
    parallelogram_max_um: float | None = None
    error: str | None = None


class SweepTrial(ResultsModel):
    """One trial: ``mean_um`` / ``max_um`` after the rigid fit (raw), ``parallelogram_*_um`` after the
    affine fit (Table 1's MaxE / MeanE) when the trial recorded them. Over a selection: the figures over
    every session's positions (MeanE weighted by positions, MaxE the largest), ``positions`` their count
    and ``sessions`` each session's own."""

    number: int
    overrides: dict[str, Any] = Field(default_factory=dict)
    mean_um: float | None = None
    max_um: float | None = None
    parallelogram_mean_um: float | None = None
    parallelogram_max_um: float | None = None
    error: str | None = None
    positions: int | None = None
    sessions: list[SweepSessionTrial] | None = None


class SweepResults(ResultsModel):
    trials: list[SweepTrial]
    best: int | None = None
    source_session: str | int | None = None
    sessions: list[str] | None = Field(None, description="an archive selection's sessions, in its order")
