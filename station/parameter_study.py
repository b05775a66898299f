"""Parameter studies (seed section 4, Table 1): measure one validation set under a grid of parameters.

One sweep core for the CLI (``station sweep``) and the orchestrator's sweep plan. Each trial measures
every image of the set with its parameters and compares displacements with the table's; the seed's
MaxE / MeanE are the errors after the well-fit parallelogram (affine fit), in mm.

**Reading of Table 1's columns.** The table heads its columns SK, TW, TH, but one sentence says they
"refer to the parameters SKIP, TESTHEIGHT, and TESTWIDTH respectively". This project follows the
headers' own abbreviations: TW = TESTWIDTH, TH = TESTHEIGHT. Trial 7 (the default) has both at 5, so
the default does not depend on the reading; trials 6, 8 and 9 do.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from station.compute import MeasureBackend
from station.displacements import ValidationError, ValidationResult, validate
from station.imagesets import ImageSet
from station.vision import MeasureParams, field_name

#: Table 1 of the seed: (FILTER, SKIP, TESTWIDTH, TESTHEIGHT) per trial, and its MaxE / MeanE (mm).
SEED_TABLE_1: tuple[tuple[int, str, int, int, int, float, float], ...] = (
    (1, "none", 20, 5, 10, 0.0372, 0.0170),
    (2, "none", 10, 5, 10, 0.0197, 0.0106),
    (3, "none", 1, 5, 10, 0.0170, 0.0081),
    (4, "mean", 1, 5, 10, 0.0150, 0.0081),
    (5, "gauss", 1, 5, 10, 0.0160, 0.0083),
    (6, "none", 1, 25, 10, 0.0177, 0.0085),
    (7, "none", 1, 5, 5, 0.0168, 0.0080),
    (8, "none", 1, 5, 15, 0.0171, 0.0081),
    (9, "none", 1, 5, 20, 0.0171, 0.0081),
)

#: Precise mode's default study: window width and outlier band.
PRECISE_GRID: dict[str, list[Any]] = {"window_sigmas": [2.0, 2.5, 3.5], "outlier_sigma": [2.5, 3.5, 5.0]}


def seed_trials() -> list[dict[str, Any]]:
    """The seed's nine trials as parameter overrides."""
    return [
        {"filter": f, "skip": sk, "testwidth": tw, "testheight": th}
        for _, f, sk, tw, th, _, _ in SEED_TABLE_1
    ]


def grid(values: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    """The Cartesian product of ``values`` (name -> list of values), in order."""
    names = list(values)
    return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*(values[n] for n in names))]


def parse_grid(specs: Sequence[str]) -> dict[str, list[str]]:
    """``NAME=V1,V2,...`` strings -> {field name: [values]}, names case-insensitive (ValueError if bad)."""
    out: dict[str, list[str]] = {}
    for spec in specs:
        name, sep, values = spec.partition("=")
        if not sep or not values.strip():
            raise ValueError(f"--grid {spec!r}: expected NAME=V1,V2,... e.g. --grid SKIP=1,10,20")
        out[field_name(name, option="--grid")] = [v.strip() for v in values.split(",") if v.strip()]
    return out


@dataclass(frozen=True)
class Trial:
    """One row of a sweep: its parameter overrides and the validation result (None if it failed)."""

    number: int
    overrides: dict[str, Any]
    params: MeasureParams
    result: ValidationResult | None
    error: str | None = None

    @property
    def max_e_mm(self) -> float:
        return self.result.comparison.affine.max / 1000.0 if self.result else float("inf")

    @property
    def mean_e_mm(self) -> float:
        return self.result.comparison.affine.mean / 1000.0 if self.result else float("inf")


def best(trials: Sequence[Trial]) -> Trial | None:
    """The best trial: lowest mean error, then lowest maximum (the seed picked trial 7 so)."""
    ok = [t for t in trials if t.result is not None]
    return min(ok, key=lambda t: (round(t.mean_e_mm, 7), t.max_e_mm)) if ok else None


def run_sweep(
    image_set: ImageSet,
    base: MeasureParams,
    overrides: Sequence[Mapping[str, Any]],
    *,
    jobs: int = 1,
    backend: MeasureBackend | None = None,
    calibration: str = "image",
    on_trial: Callable[[Trial], None] | None = None,
) -> list[Trial]:
    """Validate ``image_set`` once per parameter override; a trial whose parameters are invalid or whose
    images cannot be measured is kept with its error, and the sweep goes on. The images are measured
    on ``backend`` (``station.compute``), else in a local pool of ``jobs`` processes."""
    trials: list[Trial] = []
    for number, change in enumerate(overrides, start=1):
        params = base.with_values(**change)
        try:
            result = validate(image_set, params, jobs=jobs, backend=backend, calibration=calibration)
            trial = Trial(number, dict(change), params, result)
        except ValidationError as exc:
            trial = Trial(number, dict(change), params, None, str(exc))
        trials.append(trial)
        if on_trial is not None:
            on_trial(trial)
    return trials
