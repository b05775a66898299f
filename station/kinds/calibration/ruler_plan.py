"""The calibration plan's configurations along the cell's rulers (issue 22, item 5).

For each ruler of the cell (``[[calibration.rulers]]``, :mod:`station.ruler_config`), as
``sim.calibration_rulers.RulerPlan`` (the configuration the bench proved) lays them out:

* at each of ``ruler_positions_mm`` along it (frames 10 to 240 mm apart), the camera square on the ruler
  at the working distance, turned about its axis by each of ``ruler_turns_deg`` (plus a seeded turn of
  up to :data:`TURN_JITTER_DEG`), shifted across it by a seeded offset of up to :data:`LATERAL_MM`, in
  up to ``ruler_solutions`` joint solutions;
* at each of ``ruler_depth_positions_mm``, frames further along the optical axis by each of
  ``ruler_depth_offsets_mm`` (turn 0, the first solution): the sensor's offset along the axis;
* at each of ``ruler_lean_positions_mm``, the camera leaning ``ruler_lean_deg`` from square toward each of
  :data:`LEAN_AZIMUTHS_DEG` (its axis still meeting the ruler at the working distance): only views from
  other directions than the surface's normal place the camera along its axis.

Each is one capture, marked as a ruler's (``station.plans._ruler``). The frames at one position of one
branch (its turns, depths and leans) are one step, **re-centred** first. Each frame has a view: its own
camera axis meeting the ruler's axis at the planned position at the working distance, turned about itself
until the ruler runs along the image's short side (the widest field across it, where an arm a millimetre
or two off still sees the pattern), in the frame's branch of the arm (frames whose views are alike share
one). An :class:`~station.plans.Align` measures the ruler at each view (``measure_ruler``'s
``position_mm`` and ``offset_mm`` under the reference pixel) and moves the camera over the planned point
(within ``centre_tolerance_mm``); each frame is then taken at its planned pose shifted by the displacement
its view's Align made (the nominal model's, a translation; :class:`~station.plans.MoveAligned`, recorded
with the step as ``recentred``): frames at turns 0 and 180, whose narrower field across the ruler loses
the pattern when the arm is off, keep it in view. A resume runs an interrupted step again from its first
view, so that a step's frames share one re-centring (the analysis takes the latest attempt of a step).
The arm goes to each position through the lift poses; within a step it makes short moves.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from station.arm_route import quantised, split_move, travel, unwrap_near
from station.kinematics import KinematicsError, rot_y, rot_z, transform
from station.plans import (
    Align,
    AlignInput,
    AlignSkippedError,
    Capture,
    Correction,
    MoveAligned,
    MoveJoints,
    PlanError,
    SetSpeed,
    Settle,
    Step,
)
from station.plans._ruler import ARTIFACT_KEY, MAX_TILT_KEY, RULER

if TYPE_CHECKING:
    from station.kinds.calibration.params import CalibrationCell, CalibrationParams

FloatArray = npt.NDArray[np.float64]

LIMIT_MARGIN_DEG = 0.5
"""How far inside its limits every joint of a planned pose stays (as the crossings' configurations)."""
TURN_JITTER_DEG = 20.0
"""A seeded turn of up to this much added to each planned turn (``RulerPlan.turn_jitter_deg``)."""
LATERAL_MM = 0.3
"""A seeded offset of up to this much across the ruler (``RulerPlan.lateral_mm``)."""
LEAN_AZIMUTHS_DEG = (0.0, 90.0, 180.0, 270.0)
"""The directions the camera leans toward, from the ruler's +s about its normal."""
LEAN_TILT_MARGIN_DEG = 5.0
"""A leaning frame is measured with a tilt prior this much looser than the lean."""
SAME_BRANCH_DEG = 15.0
"""A frame's re-centring view has its joints 1 to 5 within this of the frame's (one branch of the arm)."""
SHARED_VIEW_DEG = 3.0
"""Frames of one step share a view when their views' joints 1 to 5 are within this of each other."""
MAX_RECENTRE_STEP_MM = 1.9
"""The longest single re-centring move (within the Align's 2 mm bound); longer ones go in parts."""


@dataclass(frozen=True)
class RulerConfiguration:
    """One planned frame of a ruler: where the camera should be and the joints that put it there."""

    index: int
    ruler: int
    position_mm: float
    turn_deg: float
    depth_mm: float
    lean_azimuth_deg: float | None
    solution: int
    joints_deg: tuple[float, ...]
    camera_pose: FloatArray

    def meta(self, lean_deg: float) -> dict[str, Any]:
        """The capture's metadata (a ruler's frame; the configuration's id shared with the crossings')."""
        out: dict[str, Any] = {
            ARTIFACT_KEY: RULER,
            "configuration": self.index,
            "ruler": self.ruler,
            "position_mm": self.position_mm,
            "turn_deg": self.turn_deg,
            "solution": self.solution,
            "kind": "pose",
        }
        if self.depth_mm:
            out["depth_mm"] = self.depth_mm
        if self.lean_azimuth_deg is not None:
            out["lean_azimuth_deg"] = self.lean_azimuth_deg
            out[MAX_TILT_KEY] = lean_deg + LEAN_TILT_MARGIN_DEG
        return out


def ruler_frame(origin: Sequence[float], direction: Sequence[float], normal: Sequence[float]) -> FloatArray:
    """A ruler's 4x4 frame (base frame): ``s`` along ``direction``, ``n`` into the ruler (against its upward
    ``normal``), ``t = n x s`` (so that ``n = s x t``), origin at graduation 0 on the axis."""
    n = -np.asarray(normal, dtype=float)
    n /= np.linalg.norm(n)
    s = np.asarray(direction, dtype=float)
    s = s - (s @ n) * n
    s /= np.linalg.norm(s)
    return transform(np.column_stack([s, np.cross(n, s), n]), np.asarray(origin, dtype=float))


def selected_rulers(params: CalibrationParams, n_rulers: int) -> list[int]:
    """The rulers a session captures along: ``params.rulers``, else all of the cell's when the session
    takes all its placements (``placements`` not given), none when it names its placements."""
    if params.rulers is not None:
        return list(params.rulers)
    return list(range(n_rulers)) if params.placements is None else []


def _targets(params: CalibrationParams) -> list[tuple[float, float, float, float | None, int]]:
    """(position, turn, depth offset, lean azimuth or None, solutions) of one ruler's frames."""
    out: list[tuple[float, float, float, float | None, int]] = []
    for s in params.ruler_positions_mm:
        out += [(s, turn, 0.0, None, params.ruler_solutions) for turn in params.ruler_turns_deg]
    for s in params.ruler_depth_positions_mm:
        out += [(s, 0.0, dz, None, 1) for dz in params.ruler_depth_offsets_mm]
    if params.ruler_lean_deg:
        for s in params.ruler_lean_positions_mm:
            out += [(s, 0.0, 0.0, az, 1) for az in LEAN_AZIMUTHS_DEG]
    return out


def ruler_configurations(
    params: CalibrationParams, cell: CalibrationCell, first_index: int
) -> list[RulerConfiguration]:
    """Every ruler frame the session takes, in order (ruler, branch, position), numbered from
    ``first_index`` (after the crossings' configurations)."""
    chosen = selected_rulers(params, len(cell.rulers))
    for r in chosen:
        if not 0 <= r < len(cell.rulers):
            raise PlanError(f"ruler {r} is not in the cell: [calibration] has {len(cell.rulers)} rulers")
    rng = np.random.default_rng([0x52A, params.seed])
    kin, wd = cell.kinematics, cell.working_distance_mm
    found: list[tuple[int, int, float, int, RulerConfiguration]] = []
    for r in chosen:
        ruler = cell.rulers[r]
        beyond = [x for x, *_ in _targets(params) if not 0.0 <= x <= ruler.length_mm]
        if beyond:
            raise PlanError(
                f"ruler {r} is {ruler.length_mm:g} mm long: positions {sorted(set(beyond))} mm are off it;"
                " give ruler_positions_mm (and the depth and lean positions) within it"
            )
        F = ruler_frame(ruler.origin_mm, ruler.direction, ruler.normal)
        for order, (s, turn, dz, azimuth, solutions) in enumerate(_targets(params)):
            psi = math.radians(turn + rng.uniform(-TURN_JITTER_DEG, TURN_JITTER_DEG))
            R = F[:3, :3] @ rot_z(psi)
            if azimuth is not None:
                az, lean = math.radians(azimuth), math.radians(params.ruler_lean_deg)
                R = F[:3, :3] @ rot_z(az) @ rot_y(lean) @ rot_z(-az) @ rot_z(psi)
            point = F[:3, :3] @ np.array([s, rng.uniform(-LATERAL_MM, LATERAL_MM), 0.0])
            pose = transform(R, F[:3, 3] + point - (wd + dz) * R[:, 2])
            try:
                sols = kin.inverse_all(pose)
            except KinematicsError:
                sols = []
            sols = [q for q in sols if kin.within_limits(q, margin_deg=LIMIT_MARGIN_DEG)]
            sols.sort(key=lambda q: (abs(q[1]) + abs(q[2]), q[4] < 0, abs(q[3])))
            for k, q in enumerate(sols[:solutions]):
                joints = quantised(q)
                c = RulerConfiguration(0, r, float(s), float(turn), float(dz), azimuth, k, joints, pose)
                found.append((r, k, float(s), order, c))
        if not any(f[0] == r for f in found):
            raise PlanError(
                f"ruler {r} ({ruler.name or 'unnamed'}): no joint solution within the limits puts the camera "
                "over it at the working distance; move the ruler or leave it out (rulers=[...])"
            )
    found.sort(key=lambda f: f[:4])
    return [replace(c, index=first_index + i) for i, (*_, c) in enumerate(found)]


def _branch_distance(a: Sequence[float], b: Sequence[float]) -> float:
    """How far apart two postures are, the camera's turn about its axis (joint 6) left out (deg)."""
    d = (np.subtract(a[:5], b[:5]) + 180.0) % 360.0 - 180.0
    return float(np.max(np.abs(d)))


def _view_of(cell: CalibrationCell, c: RulerConfiguration) -> tuple[float, ...] | None:
    """The joints of the view that re-centres frame ``c``: the frame's own camera axis, meeting the ruler's
    axis at the planned position at the working distance, turned about itself (the shorter way round the
    limits allow) until the ruler runs along the image's short side (the widest field across it), in the
    frame's branch (joints 1 to 5 within :data:`SAME_BRANCH_DEG` of the frame's: the arm's error there is
    the frame's, whatever the turn); None when that pose is out of reach or of the limits."""
    kin = cell.kinematics
    r = cell.rulers[c.ruler]
    F = ruler_frame(r.origin_mm, r.direction, r.normal)
    R = c.camera_pose[:3, :3]
    along = R.T @ F[:3, 0]  # the ruler's direction in the camera's frame
    turn = math.degrees(math.atan2(along[1], along[0]))  # its image angle: +/-90 wanted
    d = (turn - 90.0 + 90.0) % 180.0 - 90.0  # the smallest turn of the camera that brings it there
    point = F[:3, 3] + F[:3, 0] * c.position_mm
    for turn_by in sorted((d, d - 180.0 if d > 0 else d + 180.0), key=abs):  # either way round
        Rv = R @ rot_z(math.radians(turn_by))
        pose = transform(Rv, point - cell.working_distance_mm * Rv[:, 2])  # the frame's axis: Rv's too
        try:
            q = kin.inverse(pose, seed_deg=c.joints_deg)
        except KinematicsError:
            continue
        joints = quantised(unwrap_near(q, c.joints_deg, kin.joint_limits_deg))
        if kin.within_limits(joints, margin_deg=LIMIT_MARGIN_DEG) and (
            _branch_distance(joints, c.joints_deg) <= SAME_BRANCH_DEG
        ):
            return joints
    return None


def _views(
    cell: CalibrationCell, group: Sequence[RulerConfiguration]
) -> tuple[dict[str, tuple[float, ...]], list[str | None]]:
    """The views of a step's frames, by name (a frame shares an earlier frame's view when they are within
    :data:`SHARED_VIEW_DEG` of each other, its turn left out), and each frame's view (None: none)."""
    views: dict[str, tuple[float, ...]] = {}
    names: list[str | None] = []
    for c in group:
        q = _view_of(cell, c)
        if q is None:
            names.append(None)
            continue
        name = next((n for n, v in views.items() if _branch_distance(v, q) <= SHARED_VIEW_DEG), None)
        if name is None:
            name = f"view {len(views)}"
            views[name] = q
        names.append(name)
    return views, names


def _recentre(
    params: CalibrationParams, cell: CalibrationCell, ruler: int, s: float
) -> Any:  # Callable[[AlignInput], Correction | None]
    """The Align's correction at a ruler's view: the camera over the point ``s`` on its axis."""
    kin = cell.kinematics
    r = cell.rulers[ruler]
    F = ruler_frame(r.origin_mm, r.direction, r.normal)

    def correct(seen: AlignInput) -> Correction | None:
        if seen.ruler_st_mm is None:
            raise AlignSkippedError(
                f"ruler {ruler} is not measured at its view at {s:g} mm ({seen.error}): its frames there are"
                " skipped; check the ruler's placement in [[calibration.rulers]]"
            )
        ds, dt = s - seen.ruler_st_mm[0], -seen.ruler_st_mm[1]
        if math.hypot(ds, dt) <= params.centre_tolerance_mm:
            return None
        step = F[:3, :3] @ np.array([ds, dt, 0.0])
        size = float(np.linalg.norm(step))
        if size > MAX_RECENTRE_STEP_MM:  # a long way: go part of it, then measure again
            step *= MAX_RECENTRE_STEP_MM / size
        here = kin.forward(seen.joints_deg)
        try:
            q = kin.inverse(transform(np.eye(3), step) @ here, seed_deg=seen.joints_deg)
        except KinematicsError as exc:
            raise AlignSkippedError(f"the re-centring cannot be reached: {exc}") from exc
        near = unwrap_near(q, seen.joints_deg, kin.joint_limits_deg)
        return Correction(quantised(near), float(np.linalg.norm(step)))

    return correct


def _recentred(cell: CalibrationCell, c: RulerConfiguration, name: str, view_deg: Sequence[float]) -> Any:
    """A frame's target after the re-centring (``MoveAligned.target``): its planned pose shifted by the
    displacement the Align of view ``name`` made from the view's planned joints (the nominal model's):
    in one branch of the arm, its error at the ruler is the same whatever the camera's turn (measured
    on the simulated arm: within 0.005 mm between turns, where another wrist branch differs by a
    millimetre or more)."""
    kin = cell.kinematics
    r = cell.rulers[c.ruler]
    F = ruler_frame(r.origin_mm, r.direction, r.normal)
    planned = kin.forward(view_deg)[:3, 3]

    def target(aligned: Mapping[str, tuple[float, ...]]) -> tuple[tuple[float, ...], dict[str, Any]]:
        if name not in aligned:
            raise AlignSkippedError(f"the view {name} was not measured: the step's remaining frames skipped")
        shift = kin.forward(aligned[name])[:3, 3] - planned
        pose = transform(np.eye(3), shift) @ c.camera_pose
        try:
            q = kin.inverse(pose, seed_deg=c.joints_deg)
        except KinematicsError as exc:
            raise AlignSkippedError(f"the re-centred frame cannot be reached: {exc}") from exc
        joints = quantised(unwrap_near(q, c.joints_deg, kin.joint_limits_deg))
        offset = [round(float(v), 6) for v in F[:3, :3].T @ shift]
        return joints, {"configuration": c.index, "view": name, "offset_mm": offset}

    return target


def _groups(configs: Sequence[RulerConfiguration]) -> list[list[RulerConfiguration]]:
    """The frames at one position of one branch of one ruler (consecutive in ``configs``)."""
    out: list[list[RulerConfiguration]] = []
    for c in configs:
        if out and (out[-1][0].ruler, out[-1][0].solution, out[-1][0].position_mm) == (
            c.ruler,
            c.solution,
            c.position_mm,
        ):
            out[-1].append(c)
        else:
            out.append([c])
    return out


def ruler_steps(
    params: CalibrationParams,
    cell: CalibrationCell,
    configs: Sequence[RulerConfiguration],
    previous: tuple[float, ...] | None,
    step_limit: float,
    *,
    first: bool,
) -> Iterator[Step]:
    """The session's steps for ``configs`` from ``previous`` (joints; None: straight there): one per
    position of a branch of a ruler, numbered on from the first frame's configuration id."""
    settle: list[Any] = [Settle(params.settle_s)] if params.settle_s else []
    for g, group in enumerate(_groups(configs)):
        head = group[0]
        views, chosen = _views(cell, group)
        actions: list[Any] = [SetSpeed(params.speed_pct)] if first and g == 0 else []
        where = {ARTIFACT_KEY: RULER, "ruler": head.ruler, "position_mm": head.position_mm}
        step_meta = {**where, "configuration": head.index, "solution": head.solution}
        here = previous
        for name, view in views.items():
            if here is None:
                actions.append(MoveJoints(view))
            else:  # to the position through the lift poses, then a short move between the views
                route = (
                    travel(here, view, step_limit) if here is previous else split_move(here, view, step_limit)
                )
                actions += [MoveJoints(q) for q in route]
            actions += settle
            actions.append(
                Align(
                    correct=_recentre(params, cell, head.ruler, head.position_mm),
                    planned_deg=view,
                    meta={**step_meta, "kind": "align", "view": name},
                    settle_s=params.settle_s,
                    view=name,
                )
            )
            here = view
        for c, v in zip(group, chosen, strict=True):
            if here is None:
                actions.append(MoveJoints(c.joints_deg))
            elif here is previous:
                actions += [MoveJoints(q) for q in travel(here, c.joints_deg, step_limit)]
            else:
                actions += [MoveJoints(q) for q in split_move(here, c.joints_deg, step_limit)]
            if v is not None:
                actions.append(MoveAligned(_recentred(cell, c, v, views[v]), c.joints_deg))
            actions += settle
            actions.append(Capture(1, c.meta(params.ruler_lean_deg)))
            here = c.joints_deg
        name = f"ruler {head.ruler} at {head.position_mm:g} mm solution {head.solution}: {len(group)} frames"
        if None in chosen:
            name += f" ({chosen.count(None)} without a re-centring view in their branch)"
        yield Step(configs[0].index + g, name, tuple(actions), step_meta)
        previous = here


__all__ = [
    "LEAN_AZIMUTHS_DEG",
    "RulerConfiguration",
    "ruler_configurations",
    "ruler_frame",
    "ruler_steps",
    "selected_rulers",
]
