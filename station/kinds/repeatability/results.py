"""The ``repeatability`` kind's results (mm): each test's attained positions and ISO 9283 statistics."""

from __future__ import annotations

from typing import Any

from pydantic import Field

from station.plans._results import Check, ResultsModel

Point = tuple[float, float]


class RepeatabilityTest(ResultsModel):
    """One joint test or named sequence: attained positions (one per cycle) and their ISO 9283 statistics."""

    kind: str
    joint: int | None = None
    delta_deg: float | None = None
    targets_deg: list[list[float]] | None = None
    points_mm: list[Point]
    barycentre_mm: Point
    l_bar_mm: float
    s_l_mm: float
    rp_mm: float
    rp_ci95_mm: Point | None = None
    n_cycles: int
    planned_cycles: int | None = None
    partial: bool | None = None
    failures: list[dict[str, Any]] = Field(default_factory=list)
    # with a distance sensor: the same statistics in 3-D (x, y and the sensor's z)
    l_bar3d_mm: float | None = None
    s_l3d_mm: float | None = None
    rp3d_mm: float | None = None
    rp3d_ci95_mm: Point | None = None
    rp3d_error: str | None = None


class FailedTest(ResultsModel):
    """A test whose RP could not be computed (too few cycles measured), with the reason."""

    error: str
    n_cycles: int | None = None
    planned_cycles: int | None = None
    partial: bool | None = None


class RepeatabilityResults(ResultsModel):
    rp_mm: dict[str, float] = Field(default_factory=dict)
    n_cycles: int | None = None
    tests: dict[str, RepeatabilityTest | FailedTest] = Field(default_factory=dict)
    seed_table2_mm: dict[str, float] | None = None
    speed_pct: float | None = None
    load_kg: float | None = None
    partial: bool | None = None
    checks: list[Check] = Field(default_factory=list)

    @property
    def measured(self) -> dict[str, RepeatabilityTest]:
        """The tests that have attained positions and RP, in order."""
        return {k: t for k, t in self.tests.items() if isinstance(t, RepeatabilityTest)}
