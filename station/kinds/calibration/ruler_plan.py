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

Each is one capture, marked as a ruler's (``station.plans._ruler``): no alignment (the ruler is read
anywhere in view, the absolute position needs no centring). The arm goes there through the lift poses,
except between the turns, depths and leans at one position of one branch (a short move).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from station.arm_route import quantised, split_move, travel
from station.kinematics import KinematicsError, rot_y, rot_z, transform
from station.plans import Capture, MoveJoints, PlanError, SetSpeed, Settle, Step
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


def ruler_steps(
    params: CalibrationParams,
    configs: Sequence[RulerConfiguration],
    previous: tuple[float, ...] | None,
    step_limit: float,
    *,
    first: bool,
) -> Iterator[Step]:
    """The session's steps for ``configs``, from ``previous`` (joints; None: straight there)."""
    prev: RulerConfiguration | None = None
    for c in configs:
        near = prev is not None and (prev.ruler, prev.solution, prev.position_mm) == (
            c.ruler,
            c.solution,
            c.position_mm,
        )
        if previous is None:
            moves = [c.joints_deg]
        elif near:
            moves = split_move(previous, c.joints_deg, step_limit)
        else:
            moves = travel(previous, c.joints_deg, step_limit)
        actions: list[Any] = [SetSpeed(params.speed_pct)] if first and prev is None else []
        actions += [MoveJoints(q) for q in moves]
        if params.settle_s:
            actions.append(Settle(params.settle_s))
        meta = c.meta(params.ruler_lean_deg)
        actions.append(Capture(1, meta))
        name = f"ruler {c.ruler} at {c.position_mm:g} mm turn {c.turn_deg:g} solution {c.solution}"
        if c.depth_mm:
            name += f" depth {c.depth_mm:+g} mm"
        if c.lean_azimuth_deg is not None:
            name += f" leaning toward {c.lean_azimuth_deg:g} deg"
        yield Step(c.index, name, tuple(actions), meta)
        previous, prev = c.joints_deg, c


__all__ = [
    "LEAN_AZIMUTHS_DEG",
    "RulerConfiguration",
    "ruler_configurations",
    "ruler_frame",
    "ruler_steps",
    "selected_rulers",
]
