"""The controller self-test's checks over the :class:`station.devices.Robot` interface and the camera.

Every motion is checked by the robot (limits, step, keep-out along the path, the speed cap) before it is
sent, at the rig's low ``speed_pct``; each check leaves the arm where it found it, but the halt, which
runs last and leaves the stop latched on purpose (a person acknowledges it at the station).

* ``directions``: each joint moved by a small step (chosen so that the nominal model predicts a view
  change of about ``TARGET_SIGNAL_PX``), the crossing measured before and after; the measured change must
  point the way the nominal model says (cosine >= ``MIN_COSINE``) with a size within ``RATIO_RANGE``. A
  joint turning the other way, a camera mounted otherwise than configured, or a wrong joint zero of
  some degrees fails here.
* ``world``: the arm at N poses around where it is (a few degrees on every joint); at each, the
  controller's WORLD row against the station's arm model's flange at the attained joints: within
  ``WORLD_TOLERANCE_MM`` and ``WORLD_TOLERANCE_DEG``. Another joint zero, base origin, link length or
  WORLD convention fails here.
* ``ready``: ``ready``, then the commanded joints against the configured ready pose (within
  ``READY_TOLERANCE_DEG``), then the route back (``station.arm_route``).
* ``halt``: a slow move of joint ``HALT_JOINT`` timed unhalted, then the same move halted (``stop()``: the
  halt key) after ``HALT_FRACTION`` of that time. The arm must stop short of its target, be still, and
  stop within ``STOP_ANGLE_DEG`` of where a uniform motion over the timed move would have been when the
  key was sent.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict
from datetime import UTC, datetime

import numpy as np

from station.arm_route import go_to_reference
from station.devices import JOINT_COUNT, DeviceError, MotionRejectedError, MotionStoppedError
from station.kinematics import Kinematics, pose_from_world_row
from station.selftest._halt import check_halt
from station.selftest._result import CheckResult, SelftestResult
from station.selftest._rig import SelftestRig, free, offset
from station.selftest._view import SCALE_LEVER_PX, agreement, predicted_signal, signal, wrap_cross_deg
from station.vision import MeasurementError

__all__ = [
    "MIN_COSINE",
    "RATIO_RANGE",
    "READY_TOLERANCE_DEG",
    "TARGET_SIGNAL_PX",
    "WORLD_OFFSETS_DEG",
    "WORLD_TOLERANCE_DEG",
    "WORLD_TOLERANCE_MM",
    "check_directions",
    "check_ready",
    "check_world",
    "run_selftest",
]

log = logging.getLogger(__name__)

TARGET_SIGNAL_PX = 60.0
"""The view change (px) each joint's step is chosen to give (through the nominal model)."""
MAX_SCALE_CHANGE = 0.005
"""A joint's step moves the camera along its optical axis by at most about this fraction of the working
distance (0.34 mm at 68 mm): the crossing stays in focus."""
JOINT_STEP_RANGE_DEG = (0.01, 3.0)
"""The smallest and largest joint step of the direction check (deg)."""
MIN_COSINE = 0.8
"""The measured view change must point within about 37 deg of the predicted one."""
RATIO_RANGE = (0.5, 2.0)
"""... and be between half and twice its size."""
WORLD_OFFSETS_DEG: tuple[tuple[float, ...], ...] = (
    (2.0, -2.0, 2.0, -3.0, 3.0, -5.0),
    (-2.0, 2.0, -2.0, 3.0, -3.0, 5.0),
    (3.0, 1.0, -1.0, 5.0, 2.0, -10.0),
    (-3.0, -1.0, 1.0, -5.0, -2.0, 10.0),
    (1.0, 3.0, -3.0, -8.0, 4.0, 15.0),
    (-1.0, -3.0, 3.0, 8.0, -4.0, -15.0),
)
"""The poses of the WORLD check, as offsets (deg) from where the arm starts; those refused by the robot's
checks (keep-out, limits) are skipped."""
MIN_WORLD_POSES = 3
WORLD_TOLERANCE_MM = 0.5
"""WORLD's position against the arm model's (a joint zero 0.1 deg off moves the flange ~0.8 mm)."""
WORLD_TOLERANCE_DEG = 0.05
"""WORLD's orientation against the arm model's."""
READY_TOLERANCE_DEG = 0.01
"""The commanded joints after ``ready`` against the configured ready pose."""


def check_directions(rig: SelftestRig) -> CheckResult:
    """Each joint's direction against the camera's view of the crossing (see the module notes)."""
    start = rig.commanded()
    try:
        center, rotation, width = rig.view()
    except MeasurementError as exc:
        return CheckResult(
            "directions",
            "inconclusive",
            f"no crossing in view ({exc}): bring the camera over an artifact's crossing, in focus (station"
            " robot --config F to-reference), and run the self-test again",
        )
    before = rig.nominal.forward(start)
    joints: list[dict[str, object]] = []
    wrong: list[int] = []
    try:
        for axis in range(1, JOINT_COUNT + 1):
            probe = predicted_signal(
                before,
                rig.nominal.forward(offset(start, axis, 0.1)),
                center,
                rotation,
                rig.intrinsics,
                rig.working_distance_mm,
            )
            per_deg = float(np.linalg.norm(probe)) / 0.1
            focus_per_deg = abs(float(probe[3])) / SCALE_LEVER_PX / 0.1
            lo, hi = JOINT_STEP_RANGE_DEG
            step = min(TARGET_SIGNAL_PX / max(per_deg, 1e-9), MAX_SCALE_CHANGE / max(focus_per_deg, 1e-12))
            step = round(min(hi, max(lo, step)), 3)
            delta = step if free(rig.robot, offset(start, axis, step), start) else -step
            target = offset(start, axis, delta)
            predicted = predicted_signal(
                before, rig.nominal.forward(target), center, rotation, rig.intrinsics, rig.working_distance_mm
            )
            rig.move(target)
            try:
                moved_center, moved_rotation, moved_width = rig.view()
            finally:
                rig.move(start)
            measured = signal(
                moved_center[0] - center[0],
                moved_center[1] - center[1],
                wrap_cross_deg(moved_rotation - rotation),
                moved_width / width - 1.0,
            )
            cosine, ratio = agreement(predicted, measured)
            ok = cosine >= MIN_COSINE and RATIO_RANGE[0] <= ratio <= RATIO_RANGE[1]
            if not ok:
                wrong.append(axis)
            joints.append(
                {
                    "joint": axis,
                    "delta_deg": delta,
                    "predicted_px": [round(float(v), 3) for v in predicted],
                    "measured_px": [round(float(v), 3) for v in measured],
                    "cosine": round(cosine, 4),
                    "ratio": round(ratio, 4),
                    "passed": ok,
                }
            )
    except MeasurementError as exc:
        return CheckResult(
            "directions",
            "inconclusive",
            f"the crossing left the view during joint {len(joints) + 1}'s step ({exc}): centre it (station"
            " robot --config F jog camera x|y ...) and run the self-test again",
            {"joints": joints},
        )
    details = {"joints": joints, "min_cosine": MIN_COSINE, "ratio_range": list(RATIO_RANGE)}
    if wrong:
        return CheckResult(
            "directions",
            "failed",
            f"joint(s) {', '.join(map(str, wrong))} move the view otherwise than the station's nominal model"
            " with [camera] mount says: check the camera's mounting (translation and rotation) in"
            " station.toml, then the controller's joint directions and zeros (DIALECT.md)",
            details,
        )
    return CheckResult("directions", "passed", "every joint moves the view the way the model says", details)


def _world_errors(
    arm_model: Kinematics, joints: Sequence[float], world: Sequence[float]
) -> tuple[float, float]:
    controller = pose_from_world_row(world)
    model = arm_model.flange(np.asarray(joints, dtype=float))
    d_mm = float(np.linalg.norm(controller[:3, 3] - model[:3, 3]))
    R = controller[:3, :3].T @ model[:3, :3]
    d_deg = math.degrees(math.acos(max(-1.0, min(1.0, (float(np.trace(R)) - 1.0) / 2.0))))
    return d_mm, d_deg


def check_world(rig: SelftestRig, *, poses: int = 5) -> CheckResult:
    """WORLD against the station's arm model at ``poses`` poses around where the arm is."""
    start = rig.commanded()
    chosen: list[tuple[float, ...]] = []
    previous = start
    for shift in WORLD_OFFSETS_DEG:
        q = tuple(round(s + o, 3) for s, o in zip(start, shift, strict=True))
        if free(rig.robot, q, previous) and free(rig.robot, start, q):
            chosen.append(q)
            previous = q
        if len(chosen) == poses:
            break
    if len(chosen) < min(poses, MIN_WORLD_POSES):
        return CheckResult(
            "world",
            "inconclusive",
            f"only {len(chosen)} of the poses around the arm are free of the keep-out and the limits: start"
            " the self-test from the reference pose (station robot --config F to-reference)",
        )
    rows: list[dict[str, object]] = []
    worst_mm = worst_deg = 0.0
    try:
        for q in chosen:
            rig.move(q)
            where = rig.robot.where()
            if where.world_mm_deg is None:
                return CheckResult(
                    "world", "inconclusive", "the controller reports no WORLD row: nothing to compare"
                )
            d_mm, d_deg = _world_errors(rig.arm_model, where.joints_deg, where.world_mm_deg)
            worst_mm, worst_deg = max(worst_mm, d_mm), max(worst_deg, d_deg)
            rows.append(
                {
                    "joints_deg": list(where.joints_deg),
                    "world_mm_deg": list(where.world_mm_deg),
                    "error_mm": round(d_mm, 4),
                    "error_deg": round(d_deg, 5),
                }
            )
    finally:
        rig.move(start)
    details = {
        "poses": rows,
        "worst_mm": round(worst_mm, 4),
        "worst_deg": round(worst_deg, 5),
        "tolerance_mm": WORLD_TOLERANCE_MM,
        "tolerance_deg": WORLD_TOLERANCE_DEG,
    }
    if worst_mm > WORLD_TOLERANCE_MM or worst_deg > WORLD_TOLERANCE_DEG:
        return CheckResult(
            "world",
            "failed",
            f"the controller's WORLD differs from the station's arm model by up to {worst_mm:.3f} mm and"
            f" {worst_deg:.4f} deg: the controller's joint zeros, base origin, link lengths or WORLD's"
            " convention (DIALECT.md, still assumed 5) differ from the model; find which before calibrating",
            details,
        )
    return CheckResult(
        "world",
        "passed",
        f"WORLD agrees with the arm model at {len(rows)} poses (worst {worst_mm:.3f} mm,"
        f" {worst_deg:.4f} deg)",
        details,
    )


def check_ready(rig: SelftestRig) -> CheckResult:
    """``ready`` against the configured ready pose, then the route back."""
    if rig.ready_pose_deg is None:
        return CheckResult(
            "ready", "inconclusive", "no ready pose is configured ([robot] safety.ready_pose_deg)"
        )
    start = rig.commanded()
    rig.speed(rig.speed_pct)
    try:
        rig.robot.ready()
    except MotionRejectedError as exc:
        return CheckResult(
            "ready",
            "inconclusive",
            f"the path to the ready pose is refused ({exc}): check the ready pose by hand from the pendant,"
            " the cell watched",
        )
    where = rig.robot.where()
    go_to_reference(rig.robot, start, max_step_deg=rig.max_step_deg)
    worst = max(abs(a - b) for a, b in zip(where.commanded_joints_deg, rig.ready_pose_deg, strict=True))
    details = {
        "configured_deg": list(rig.ready_pose_deg),
        "commanded_deg": list(where.commanded_joints_deg),
        "worst_deg": round(worst, 4),
        "tolerance_deg": READY_TOLERANCE_DEG,
    }
    if worst > READY_TOLERANCE_DEG:
        return CheckResult(
            "ready",
            "failed",
            f"ready went to {list(where.commanded_joints_deg)}, not the configured"
            f" {list(rig.ready_pose_deg)}: set [robot] safety.ready_pose_deg to where ready goes (its path"
            " is checked against the keep-out with it)",
            details,
        )
    return CheckResult("ready", "passed", "ready goes to the configured ready pose", details)


_CHECKS: dict[str, Callable[[SelftestRig], CheckResult]] = {
    "directions": check_directions,
    "world": check_world,
    "ready": check_ready,
    "halt": check_halt,
}


def run_selftest(rig: SelftestRig, *, checks: Sequence[str] = tuple(_CHECKS)) -> SelftestResult:
    """Run ``checks`` (in ``CHECK_NAMES`` order) and return what they found.

    The robot must be connected, homed and unlatched (``clear_stop`` raises what to do otherwise), the
    camera over a crossing for ``directions``. A device error ends that check as ``failed`` (its text is
    the summary) and the later ones as ``not_run``; ``halt`` leaves the stop latched (``latched``).
    """
    unknown = [c for c in checks if c not in _CHECKS]
    if unknown:
        raise ValueError(f"unknown self-test check(s) {unknown}: choose from {list(_CHECKS)}")
    rig.robot.clear_stop()
    started = datetime.now(UTC).isoformat()
    start = rig.commanded()
    results: list[CheckResult] = []
    broken: str | None = None
    for name in _CHECKS:
        if name not in checks:
            continue
        if broken is not None:
            results.append(CheckResult(name, "not_run", f"not run: {broken}"))
            continue
        log.info("self-test: %s", name)
        try:
            results.append(_CHECKS[name](rig))
        except DeviceError as exc:
            broken = f"the {name} check failed with a device error"
            results.append(CheckResult(name, "failed", f"{type(exc).__name__}: {exc}"))
    latched = False
    try:
        rig.robot.clear_stop()
    except MotionStoppedError:
        latched = True
    return SelftestResult(
        checks=tuple(results),
        identity=asdict(rig.robot.identity()),
        latched=latched,
        start_joints_deg=start,
        started_at=started,
        finished_at=datetime.now(UTC).isoformat(),
    )
