"""Session plans: what a session does, as a list of steps over the device interfaces.

A plan is a typed, validated parameter model plus three functions (see :class:`Plan`):

* ``steps(params, ctx)`` yields the session's :class:`Step` s, each a short list of :data:`Action` s
  (move the arm, turn the table, settle, capture). Steps are the runner's safe points: it pauses, stops
  and resumes between them. A plan's steps are a pure function of its parameters and the context, so
  the runner can list them all for pre-flight (every motion checked before anything moves) and for
  resuming a session after a crash (skip the steps recorded as done).
* ``resume_prelude(params, ctx, next_step)`` gives the steps to run before resuming at ``next_step``
  (e.g. return to the reference pose and capture the reference again).
* ``analyse(params, ctx, captures)`` turns the session's measured captures into its results, with its
  gates' verdicts in ``results["checks"]`` (``station.plans._gates``): a result that fails a ``fail``
  check ends the session ``failed``.
* ``reference_pose(params, ctx)`` says where a session of the plan starts (:class:`ReferencePose`): the
  runner makes the arm's route there from wherever it is the session's first motion
  (:mod:`station.arm_route`; checked in pre-flight from the arm's commanded position), or, for a plan
  that must not move the arm, refuses at pre-flight when it is not there. Steps and resume preludes
  start from that pose.

Two optional methods:

* ``resume_from(params, ctx, steps, next_step) -> (index, reason)``: the plan's resume rule, the first
  step a resume runs again (done or not), so that a population is never made of two runs (repeatability
  reruns the interrupted test from its start). Without it a resume continues at ``next_step``.
* ``check_progress(params, ctx, captures)``: live gates, called once each step is stored and measured;
  it raises ``GateError`` to stop the session at once when what was measured cannot be right.

And a declaration: ``table_content(params)`` says what must lie on the X-Y table (``"cross"``,
``"ruler"``, ``"target"`` or None); the runner asks the operator for it before pre-flight
(``station.table_content``).

Offline plans (``sweep``, ``reanalyse``) have no device actions: their steps carry a :class:`Compute`.
Plans never touch a concrete driver; the runner executes the actions (architecture: plans and the
runner see devices only through ``station.devices``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from pydantic import BaseModel, ValidationError

from station._pydantic import problems as describe

if TYPE_CHECKING:
    from station.compute import MeasureBackend
    from station.record import Record
    from station.vision import MeasureParams


@dataclass(frozen=True)
class MoveJoints:
    """Move the arm to six absolute joint angles (deg)."""

    target_deg: tuple[float, ...]


@dataclass(frozen=True)
class MoveTable:
    """Set the X-Y table to (x, y) mm; ``overshoot`` marks the approach move that takes up backlash."""

    x_mm: float
    y_mm: float
    overshoot: bool = False


@dataclass(frozen=True)
class SetSpeed:
    """Set the arm's speed override (percent)."""

    percent: int


@dataclass(frozen=True)
class Settle:
    """Wait for the arm to settle: ``seconds`` after arrival."""

    seconds: float


@dataclass(frozen=True)
class Capture:
    """Grab ``frames`` frames, store each raw, measure each; ``meta`` goes with every capture."""

    frames: int
    meta: Mapping[str, Any]


@dataclass(frozen=True)
class Compute:
    """Offline work (no device): ``run(ctx)`` returns a JSON-ready dict stored as the step's data."""

    run: Callable[[PlanContext], dict[str, Any]]
    label: str = ""


@dataclass(frozen=True)
class DeviceCheck:
    """Run ``run(devices)`` on the station's connected devices (``StationDevices``): a procedure that
    drives them itself, as the controller self-test does (each of its moves checked by the robot); the
    JSON-ready dict it returns is stored as the step's data."""

    run: Callable[[Any], dict[str, Any]]
    label: str = ""


@dataclass(frozen=True)
class MoveOffset:
    """Move the arm to the pose the last :class:`Align` reached plus ``offset_deg`` (six joint deltas).

    Pre-flight checks it from the step's planned pose; the runner checks it again with ``check_move``
    from where the arm is before sending it.
    """

    offset_deg: tuple[float, ...]


@dataclass(frozen=True)
class Correction:
    """What :attr:`Align.correct` asks for: a joint target and the camera translation it makes (mm)."""

    target_deg: tuple[float, ...]
    translation_mm: float


@dataclass(frozen=True)
class AlignInput:
    """What :attr:`Align.correct` sees: where the arm is (encoders), the measured crossing (px; None with
    the measurement's ``error`` when it failed), the distance sensor's reading (None without a sensor).

    An Align whose ``meta`` marks a ruler's view (``station.plans._ruler``) measures the ruler instead:
    ``ruler_st_mm`` is then its ``(position_mm, offset_mm)`` under the reference pixel and ``center_px``
    is None (both None, with ``error``, when the ruler is not measured).
    """

    joints_deg: tuple[float, ...]
    center_px: tuple[float, float] | None
    z_mm: float | None
    image_size: tuple[int, int]
    error: str | None = None
    ruler_st_mm: tuple[float, float] | None = None


class AlignSkippedError(Exception):
    """An :class:`Align` cannot bring the crossing into place here (not seen, correction out of bounds):
    the step's remaining actions are skipped and the reason recorded with the step."""


@dataclass(frozen=True)
class Align:
    """A data-dependent correction before a capture (focus and re-centring).

    The runner grabs a frame (stored like any capture, ``meta`` role ``align``), measures it, reads the
    distance sensor when there is one, and calls ``correct`` with an :class:`AlignInput`: ``None`` when
    aligned, else a :class:`Correction`. A correction moving the camera more than ``max_translation_mm``,
    or putting a joint more than ``max_joint_deg`` from the step's planned pose, is refused
    (:class:`AlignSkippedError`); one within is checked with ``check_move`` and sent, then the arm
    settles ``settle_s`` and the loop repeats, at most ``max_iterations`` times. ``correct`` raises
    :class:`AlignSkippedError` when the crossing is not seen.
    """

    correct: Callable[[AlignInput], Correction | None]
    planned_deg: tuple[float, ...]
    meta: Mapping[str, Any]
    max_translation_mm: float = 2.0
    max_joint_deg: float = 2.0
    max_iterations: int = 6
    settle_s: float = 0.25
    view: str = ""
    """When set, the aligned joints are also kept under ``aligned_views[view]`` in the step's data: what a
    later :class:`MoveAligned` of the step starts from (several views, one name each)."""


@dataclass(frozen=True)
class MoveAligned:
    """Move the arm to a pose that depends on where the step's last :class:`Align` ended.

    ``target(views)`` (each named Align's final encoder reading, :attr:`Align.view`) returns the joints
    and what to record of the correction (stored with the step's data under ``recentred``, one entry per
    move). Pre-flight
    checks ``planned_deg`` (the target with no correction); the runner refuses a target more than
    ``max_joint_deg`` from it (:class:`AlignSkippedError`: the rest of the step is skipped) and checks
    the move with ``check_move`` before it is sent.
    """

    target: Callable[[Mapping[str, tuple[float, ...]]], tuple[tuple[float, ...], Mapping[str, Any]]]
    planned_deg: tuple[float, ...]
    max_joint_deg: float = 2.0


Action = (
    MoveJoints
    | MoveTable
    | SetSpeed
    | Settle
    | Capture
    | Compute
    | Align
    | MoveOffset
    | MoveAligned
    | DeviceCheck
)


@dataclass(frozen=True)
class Step:
    """One safe-point-to-safe-point unit of a session."""

    index: int
    name: str
    actions: tuple[Action, ...]
    meta: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class CaptureResult:
    """What analysis gets per capture: its metadata and its measurement (``None`` when it failed).

    ``z_mm``: the distance sensor's reading with the frame (mm), ``None`` without a sensor or a valid
    reading (``meta["z_error"]`` then says why).
    """

    capture_id: int
    step_index: int
    frame_index: int
    meta: Mapping[str, Any]
    measurement: Mapping[str, Any] | None
    width: int = 0
    height: int = 0
    z_mm: float | None = None


@dataclass
class PlanContext:
    """What a plan may know about the station.

    ``reference_joints_deg``: the configured reference pose (where the camera sees the crossing).
    ``camera_height_mm``: height of the camera's front above the artifact plane for given joints, when
    the robot's configuration says where both are (used to choose move directions away from the
    artifact). ``measure_params``: the session's measurement parameters. ``record``: the record (offline
    plans read stored sessions from it). ``jobs``: worker processes for offline plans when no
    ``compute`` backend is given. ``compute``: where offline plans measure (the local pool, a Dask
    cluster; see ``station.compute``). ``cancelled``: true once the session is being aborted, for
    long computations to poll (a backend then cancels its tasks). ``cell``: the plan's own view of the
    station, made by its optional ``cell_from_config`` from the station's configuration (live) or from
    the one a stored session recorded (a re-analysis); ``None`` for plans without one or when the
    configuration lacks what it needs. ``plan_of``: the registry's plan lookup (``station.kinds``), for
    a plan that runs another kind's analysis (``reanalyse``).
    """

    measure_params: MeasureParams
    reference_joints_deg: tuple[float, ...] | None = None
    camera_height_mm: Callable[[Sequence[float]], float] | None = None
    record: Record | None = None
    session_id: str | None = None
    jobs: int = 1
    cell: Any = None
    compute: MeasureBackend | None = None
    cancelled: Callable[[], bool] = field(default=lambda: False)
    plan_of: Callable[[str], Plan] | None = None


@dataclass(frozen=True)
class ReferencePose:
    """Where a plan's sessions start (six joint angles, deg). ``route``: the runner takes the arm there
    from wherever it is before the first step (and before a resume's prelude); ``False``: the plan never
    moves the arm (a validation: the operator's hands are at the table under it) and pre-flight refuses
    when the arm is not there."""

    joints_deg: tuple[float, ...]
    route: bool = True


class PlanError(ValueError):
    """A plan cannot run with these parameters or this station (the message says what to change)."""


class Plan(Protocol):
    """A session kind: its parameter model and its three functions."""

    @property
    def name(self) -> str: ...

    @property
    def Params(self) -> type[BaseModel]: ...  # noqa: N802 - a class, named as one

    @property
    def needs(self) -> frozenset[str]:
        """The devices it drives: "robot", "camera", "table", "distance_sensor" (``StationDevices``' names);
        empty for an offline plan."""

    def steps(self, params: Any, ctx: PlanContext) -> Iterator[Step]: ...

    def resume_prelude(self, params: Any, ctx: PlanContext, next_step: Step) -> list[Step]: ...

    def analyse(self, params: Any, ctx: PlanContext, captures: Sequence[CaptureResult]) -> dict[str, Any]: ...

    def reference_pose(self, params: Any, ctx: PlanContext) -> ReferencePose | None:
        """Where its sessions start (None: anywhere, the plan does not need the arm)."""

    # Optional (looked up with getattr): ``resume_from`` (what a resume reruns), ``check_progress`` (live
    # gates), ``source_session(params)`` (an offline plan's stored session) and
    # ``cell_from_config(config, measure_params)``: the plan's view of the station (``PlanContext.cell``)
    # from a configuration as JSON, the live station's or the one a stored session recorded.


def station_cell(plan: Plan, config: Mapping[str, Any] | None, measure_params: MeasureParams) -> Any:
    """``PlanContext.cell`` for ``plan`` on the station ``config`` describes (None without one)."""
    make = getattr(plan, "cell_from_config", None)
    return None if make is None or config is None else make(config, measure_params)


def parse_params(plan: Plan, values: Mapping[str, Any]) -> BaseModel:
    """Validate a plan's parameters; PlanError naming every bad field and what is allowed."""
    try:
        return plan.Params.model_validate(dict(values))
    except ValidationError as exc:
        problems = describe(exc, plan.name)
        raise PlanError(f"{plan.name} parameters: {problems}") from exc


__all__ = [
    "Action",
    "Align",
    "AlignInput",
    "AlignSkippedError",
    "Capture",
    "CaptureResult",
    "Compute",
    "Correction",
    "DeviceCheck",
    "MoveAligned",
    "MoveJoints",
    "MoveOffset",
    "MoveTable",
    "Plan",
    "PlanContext",
    "PlanError",
    "ReferencePose",
    "SetSpeed",
    "Settle",
    "Step",
    "parse_params",
    "station_cell",
]
