"""The session mapping a report is drawn from, parsed and checked at the boundary.

A session comes from the record (or its JSON export) as a plain mapping: ``id``, ``kind``, ``state``,
``created_at`` (ISO 8601), ``params``, ``identities``, ``software``, ``results`` (None until the session
has results) and, for a session that did not succeed, optionally ``error``. Results are parsed with
pydantic so that a malformed record is named precisely (``results.positions.3.measured_um``) instead of
failing somewhere inside matplotlib.

Units are in the key names: validation in um, repeatability in mm, sweep trials in um; calibration's
relative error in um, its residuals in mm, each parameter with its own ``unit`` (mm or deg).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from pydantic import BaseModel, ConfigDict, Field
from pydantic import ValidationError as PydanticValidationError

KINDS = ("validation", "repeatability", "sweep", "calibration", "reanalyse")

Point = tuple[float, float]


class ReportError(ValueError):
    """A session cannot be reported: not a session mapping, or its results are malformed."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)


class Fit(_Model):
    """One best fit of commanded to measured displacements, as ``station validate --json`` prints it."""

    mean_um: float
    max_um: float
    rms_um: float | None = None
    scale: float | None = None
    rotation_deg: float | None = None


class Check(_Model):
    """One gate's verdict (``results.checks``): a failed ``fail`` check failed the session."""

    name: str
    passed: bool
    value: float | None = None
    limit: float | tuple[float, float] | None = None
    severity: str = "fail"
    message: str = ""


class Position(_Model):
    """One table position. ``error_*_um`` = measured - fitted commanded, in the measured (artifact) axes;
    no parallelogram error when the positions measured lie on a line (a session stopped early)."""

    index: int
    commanded_um: Point
    measured_um: Point
    error_um: Point
    error_parallelogram_um: Point | None = None


class ScaleCalibration(_Model):
    groove_width_mm: float
    u_mm: float
    session_id: str | int | None = None


class ValidationResults(_Model):
    mean_um: float
    max_um: float
    parallelogram_mean_um: float | None = None
    parallelogram_max_um: float | None = None
    scale: float
    groove_width_mm: float | None
    rigid: Fit
    similarity: Fit
    affine: Fit | None = None
    positions: list[Position] = Field(default_factory=list)
    scale_calibration: ScaleCalibration | None = None
    groove_width_u_mm: float | None = None
    groove_width_used_mm: float | None = None
    approach: str | None = None
    failures: list[dict[str, Any]] = Field(default_factory=list)
    n_positions: int | None = None
    partial: bool | None = None
    checks: list[Check] = Field(default_factory=list)


class RepeatabilityTest(_Model):
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


class FailedTest(_Model):
    """A test whose RP could not be computed (too few cycles measured), with the reason."""

    error: str
    n_cycles: int | None = None
    planned_cycles: int | None = None
    partial: bool | None = None


class RepeatabilityResults(_Model):
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


class SweepTrial(_Model):
    """One trial: ``mean_um`` / ``max_um`` after the rigid fit (raw), ``parallelogram_*_um`` after the
    affine fit (Table 1's MaxE / MeanE) when the trial recorded them."""

    number: int
    overrides: dict[str, Any] = Field(default_factory=dict)
    mean_um: float | None = None
    max_um: float | None = None
    parallelogram_mean_um: float | None = None
    parallelogram_max_um: float | None = None
    error: str | None = None


class SweepResults(_Model):
    trials: list[SweepTrial]
    best: int | None = None
    source_session: str | int | None = None


class RelativeError(_Model):
    """The issue's figure (um): the mean in-plane distance between held-out configurations' crossings of one
    placement, with the nominal (``before``) and the calibrated (``after``) model, and the ``floor`` (what
    repeatability and noise leave). Any may be missing (too few held-out pairs, no return captures)."""

    before: float | None = None
    after: float | None = None
    floor: float | None = None


class CalibrationParameter(_Model):
    """One model parameter: nominal and estimate in ``unit``; ``sigma`` and ``interval`` (95 %) only when
    identified; ``structural``: no pose set identifies it (it stays at nominal)."""

    name: str
    unit: str = ""
    nominal: float
    estimate: float
    interval: tuple[float, float] | None = None
    sigma: float | None = None
    identified: bool
    structural: bool = False


class ResidualSummary(_Model):
    """Residuals of a set of observations (mm): the image's (at the focal plane) and the sensor's."""

    n: int
    rms_xy_mm: float
    max_xy_mm: float
    n_z: int = 0
    rms_z_mm: float | None = None
    max_z_mm: float | None = None
    xy_um: list[float] | None = None
    """Each observation's image residual (µm); None in results written before it was recorded."""
    z_um: list[float] | None = None


class Deficiency(_Model):
    """A parameter (or combination) the data cannot determine, as the combination of others it trades
    with (``{other: k}`` in natural units) and how far from exact (``residual``; 0 = indistinguishable)."""

    name: str
    combination: dict[str, float] = Field(default_factory=dict)
    residual: float | None = None
    reason: str = ""


class Identifiability(_Model):
    """The SVD of the column-scaled Jacobian of all parameters (singular values descending), the
    structural list, and what this pose set fails to determine (``deficient``, ``dropped``)."""

    rcond: float
    singular_values: list[float] = Field(default_factory=list)
    null_dimension: int
    structural: list[Deficiency] = Field(default_factory=list)
    structural_verified: bool | None = None
    deficient: list[str] = Field(default_factory=list)
    dropped: list[Deficiency] = Field(default_factory=list)


class CrossValidation(_Model):
    held_out_configurations: list[int] = Field(default_factory=list)
    n_observations: int = 0
    before: ResidualSummary | None = None
    after: ResidualSummary | None = None


class FitSummary(_Model):
    method: str
    evaluations: int
    status: int
    message: str = ""
    observations: int
    residuals: int
    dof: int
    s2: float | None = None
    loss: str = "linear"
    f_scale: float | None = None
    downweighted: int = 0


class CalibrationDocument(_Model):
    """The parts of the versioned ``CalibrationResult`` JSON (``station.calibration``) a report shows."""

    schema_version: int | None = None
    software_version: str | None = None
    created: str | None = None
    identifiability: Identifiability
    residuals: dict[str, ResidualSummary] = Field(default_factory=dict)
    cross_validation: CrossValidation | None = None
    fit: FitSummary | None = None
    sigmas_mm: dict[str, float] = Field(default_factory=dict)


class CalibrationResults(_Model):
    """A calibration session's results (``station.calibration_session.analyse_calibration``)."""

    relative_error_um: RelativeError
    floor_source: str | None = None
    condition_number: float
    unidentifiable: list[str] = Field(default_factory=list)
    identified_count: int
    parameters: list[CalibrationParameter]
    observations: int | None = None
    configurations: int | None = None
    placements: list[int] = Field(default_factory=list)
    held_out_configurations: list[int] = Field(default_factory=list)
    planned_configurations: int | None = None
    left_out: list[Any] = Field(default_factory=list)
    calibration: CalibrationDocument
    checks: list[Check] = Field(default_factory=list)


Results = ValidationResults | RepeatabilityResults | SweepResults | CalibrationResults


@dataclass(frozen=True)
class Session:
    """A session's facts for the report header, and its results parsed (None when there are none).

    ``results_kind``: the kind the results are drawn as (a re-analysis is drawn as its source's kind);
    ``problem``: why the results could not be parsed (only for sessions that did not succeed, whose
    results may be partial; ``raw_results`` then keeps them for the report to show as they are).
    """

    id: str
    kind: str
    state: str
    created_at: str
    params: Mapping[str, Any]
    identities: Mapping[str, Any]
    software: Mapping[str, Any]
    error: str | None
    source_session: str | None
    results_kind: str | None
    results: Results | None
    raw_results: Any
    problem: str | None

    @property
    def succeeded(self) -> bool:
        return self.state == "succeeded"

    @property
    def failed_checks(self) -> list[Check]:
        """The ``fail`` checks its results did not pass (why a session with results failed)."""
        checks: list[Check] = getattr(self.results, "checks", [])
        return [c for c in checks if c.severity == "fail" and not c.passed]


_PARSERS: dict[
    str, type[ValidationResults] | type[RepeatabilityResults] | type[SweepResults] | type[CalibrationResults]
] = {
    "validation": ValidationResults,
    "repeatability": RepeatabilityResults,
    "sweep": SweepResults,
    "calibration": CalibrationResults,
}


def _error_text(error: Any) -> str | None:
    if error is None or error == "":
        return None
    if isinstance(error, Mapping):
        message = error.get("message") or error.get("error")
        code = error.get("code")
        if message is not None:
            return f"{message} ({code})" if code else str(message)
        return json.dumps(error, default=str)
    return str(error)


def _describe(exc: PydanticValidationError) -> str:
    first = exc.errors(include_url=False)[0]
    where = ".".join(str(p) for p in ("results", *first["loc"]))
    more = f" (and {exc.error_count() - 1} more)" if exc.error_count() > 1 else ""
    return f"{where}: {first['msg']}{more}"


def _parse_results(kind: str, raw: Any) -> tuple[str | None, str | None, Results | None]:
    """(kind drawn, source session, parsed results) of a session's ``results``."""
    if raw is None:
        return None, None, None
    if not isinstance(raw, Mapping):
        raise ReportError(f"results must be an object, got {type(raw).__name__}")
    source = raw.get("source_session")
    source_id = None if source is None else str(source)
    if kind == "reanalyse":
        inner = raw.get("kind")
        if inner is None:
            found = [k for k in KINDS if raw.get(k) is not None]
            inner = found[0] if len(found) == 1 else None
        if inner not in KINDS or raw.get(inner) is None:
            raise ReportError(
                "results of a reanalyse session must name the source's kind ('kind') and hold its results "
                f"under that name, one of {', '.join(map(repr, KINDS))}"
            )
        drawn, inner_source, results = _parse_results(str(inner), raw[inner])
        return drawn, source_id if source_id is not None else inner_source, results
    try:
        return kind, source_id, _PARSERS[kind].model_validate(raw)
    except PydanticValidationError as exc:
        raise ReportError(_describe(exc)) from None


def parse_session(session: Mapping[str, Any]) -> Session:
    """Check a session mapping and parse its results (ReportError naming the field when malformed)."""
    if not isinstance(session, Mapping):
        raise ReportError(f"a session must be a mapping, got {type(session).__name__}")
    missing = [k for k in ("id", "kind", "state") if session.get(k) is None]
    if missing:
        raise ReportError(f"the session lacks {', '.join(map(repr, missing))}: is this a session record?")
    sid, kind, state = str(session["id"]), str(session["kind"]), str(session["state"])
    if kind not in KINDS:
        raise ReportError(f"session {sid}: unknown kind {kind!r}; known: {', '.join(KINDS)}")
    raw = session.get("results")
    problem = None
    try:
        results_kind, source, results = _parse_results(kind, raw)
    except ReportError as exc:
        if state == "succeeded":
            raise ReportError(f"session {sid} ({kind}, succeeded) has malformed results: {exc}") from None
        results_kind, source, results, problem = None, None, None, str(exc)
        if isinstance(raw, Mapping) and raw.get("source_session") is not None:
            source = str(raw["source_session"])
    return Session(
        id=sid,
        kind=kind,
        state=state,
        created_at=str(session.get("created_at") or ""),
        params=_mapping(session.get("params")),
        identities=_mapping(session.get("identities")),
        software=_mapping(session.get("software")),
        error=_error_text(session.get("error")),
        source_session=source,
        results_kind=results_kind,
        results=results,
        raw_results=raw,
        problem=problem,
    )


def _mapping(value: Any) -> Mapping[str, Any]:
    return value if isinstance(value, Mapping) else {}


def format_date(iso: str) -> str:
    """An ISO 8601 time as ``YYYY-MM-DD HH:MM:SS UTC`` (or with its offset); unparsable text as given."""
    try:
        when = datetime.fromisoformat(iso)
    except ValueError:
        return iso
    if when.tzinfo is None:
        return when.strftime("%Y-%m-%d %H:%M:%S")
    if when.utcoffset() == UTC.utcoffset(None):
        return when.strftime("%Y-%m-%d %H:%M:%S UTC")
    return when.strftime("%Y-%m-%d %H:%M:%S %z")


def format_value(value: Any) -> str:
    """A parameter or identity value as compact text (JSON for structures, "-" for none)."""
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    try:
        return json.dumps(value, default=str, allow_nan=True)
    except (TypeError, ValueError):
        return str(value)
