"""The seed's repeatability protocol simulated in truth space: no images, no pty, no waiting.

The controller twin's own arm model (``ControllerTwin(...).arm``, never started: no pty) runs on an
injected clock and the world follows it, with the flange's Cartesian error indexed by the arm's motions;
after each return to the reference pose the capture is the world's true tool point (where the optical
axis meets the artifact, relative to the crossing, in the artifact's axes: the position the
repeatability plan measures, ``station/kinds/repeatability/plan.py``), what a perfect measurement gives.
This is what fits :mod:`sim.arm_errors` to the seed's Table 2 and what the station's simulated
sessions are compared with.

Protocol (seed section 5; the repeatability plan of the sessions issue): at the world's reference pose,
for each test, ``warmup_cycles`` uncaptured and then ``cycles`` captured cycles of "move away, come
back, wait ``settle_s``, capture". A joint test moves joint ``j`` by ``delta_deg`` in the direction that
takes the camera away from the artifact (:func:`away_signs`) and back; a sequence visits its joint
targets and comes back. Like the robot driver's ``move_joints``, a multi-joint move is made of one
single-joint motion per joint that changes, in the order 1-6. Tests run one after another in one world
(the arm warms up over the session), in the order given.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from sim.arm_errors import DEFAULT_ARM_ERRORS, ArmErrorModel
from sim.controller import ControllerTwin, TwinSettings
from sim.world import World, WorldSpec
from station.kinematics import Kinematics
from station.metrology import Repeatability, repeatability

FloatArray = npt.NDArray[np.float64]
JOINTS = 6

#: Two sequences of arbitrary motion of all six joints (offsets from the reference pose, deg), like the
#: seed's Figures 16 and 17 (the seed does not give its sequences): each visits two poses, then returns.
#: No joint moves more than 30 deg between two poses: the host's maximum step (the driver's safety).
SEQUENCE_OFFSETS_DEG: dict[str, tuple[tuple[float, ...], ...]] = {
    "S1": ((10.0, -8.0, -12.0, 15.0, -10.0, 20.0), (-5.0, -15.0, -5.0, -10.0, 12.0, -8.0)),
    "S2": ((-12.0, -5.0, -15.0, -20.0, 8.0, -25.0), (8.0, -12.0, -8.0, 8.0, -6.0, 4.0)),
}


def sequences_at(reference_deg: npt.ArrayLike) -> dict[str, list[list[float]]]:
    """The sequences' absolute joint targets (deg) around ``reference_deg`` (the plan's ``sequences``)."""
    ref = np.asarray(reference_deg, dtype=float)
    return {
        name: [(ref + np.asarray(offset)).tolist() for offset in offsets]
        for name, offsets in SEQUENCE_OFFSETS_DEG.items()
    }


def away_signs(world: World, delta_deg: float = 10.0) -> tuple[int, ...]:
    """Per joint, the sign (+1/-1) of a ``delta_deg`` move that does not bring the camera toward the artifact.

    Decided as the station's repeatability plan decides it: the camera's height above the (level)
    table from the nominal kinematics, +1 on a tie (within 1 um: joints 1, 4, 5 and 6 at the sim
    world's reference pose). The true arm's small tilts must not flip a tie.
    """
    ref = np.asarray(world.spec.reference_joints_deg, dtype=float)
    nominal = Kinematics(tool=world.kinematics.tool)

    def height(q: FloatArray) -> float:
        return float(nominal.forward(tuple(q))[2, 3])

    signs = []
    for j in range(JOINTS):
        step = np.zeros(JOINTS)
        step[j] = delta_deg
        up, down = height(ref + step), height(ref - step)
        signs.append(-1 if down > up + 1e-3 else 1)
    return tuple(signs)


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@dataclass(frozen=True)
class ProtocolSettings:
    """The protocol's conditions (seed section 5: about 80 % speed, delta not given; 10 deg here)."""

    cycles: int = 30
    warmup_cycles: int = 3
    delta_deg: float = 10.0
    speed_pct: int = 80
    settle_s: float = 0.25
    joints: tuple[int, ...] = (1, 2, 3, 4, 5, 6)
    sequences: bool = True

    def __post_init__(self) -> None:
        if self.cycles < 2 or self.warmup_cycles < 0:
            raise ValueError(
                f"cycles must be >= 2 and warmup_cycles >= 0, got {self.cycles}, {self.warmup_cycles}"
            )
        if not (math.isfinite(self.delta_deg) and self.delta_deg > 0):
            raise ValueError(f"delta_deg must be > 0, got {self.delta_deg!r}")
        if not 1 <= self.speed_pct <= 100 or self.settle_s < 0:
            raise ValueError(
                f"speed_pct must be 1-100 and settle_s >= 0, got {self.speed_pct}, {self.settle_s}"
            )
        if any(j not in range(1, JOINTS + 1) for j in self.joints):
            raise ValueError(f"joints must be numbers 1-6, got {self.joints!r}")


@dataclass(frozen=True)
class ProtocolRun:
    """One simulated session: the captured true positions (mm, (N, 2)) and RP per test."""

    points_mm: dict[str, FloatArray]
    results: dict[str, Repeatability]

    @property
    def rp_mm(self) -> dict[str, float]:
        return {name: r.rp for name, r in self.results.items()}


class _Session:
    """The twin's arm on a fake clock, the world following it."""

    def __init__(self, model: ArmErrorModel, spec: WorldSpec, seed: int, protocol: ProtocolSettings) -> None:
        self.clock = _Clock()
        settings = TwinSettings(
            **model.joints.twin_options(),
            seed=seed,
            speed_pct=protocol.speed_pct,
            start_pose_deg=tuple(spec.reference_joints_deg),
        )
        self._twin = ControllerTwin(settings, clock=self.clock)  # not started: no pty, no thread
        self.arm = self._twin.arm
        arm = self.arm
        self.world = World(
            replace(spec, flange_errors=model.flange),
            joints=arm.actual_exact,
            moves=lambda: arm.moves,
            seed=seed,
        )
        self.settle_s = protocol.settle_s

    def close(self) -> None:
        self._twin.close()

    def go(self, target_deg: npt.ArrayLike) -> None:
        """Single-joint motions to ``target_deg`` in the order 1-6, each awaited; then settle."""
        target = np.asarray(target_deg, dtype=float)
        for axis in range(1, JOINTS + 1):
            delta = float(target[axis - 1]) - float(self.arm.commanded()[axis - 1])
            if delta != 0.0:
                self.clock.t += self.arm.move_joint(axis, delta)
        self.clock.t += self.settle_s / self.arm.params.time_scale

    def capture(self) -> tuple[float, float]:
        return self.world.center_mm(tool_point=True)


def simulate_repeatability(
    model: ArmErrorModel = DEFAULT_ARM_ERRORS,
    *,
    seed: int = 0,
    spec: WorldSpec | None = None,
    protocol: ProtocolSettings | None = None,
    sequences: Mapping[str, Sequence[Sequence[float]]] | None = None,
) -> ProtocolRun:
    """Run the repeatability protocol on the twin's arm model in truth space; RP per test (mm).

    Parameters
    ----------
    model
        The arm's error model (its joint part drives the twin's arm, its Cartesian part the world).
    seed
        Seeds the arm's noise and the world's Cartesian error.
    spec
        The world (reference pose, camera, artifact); its ``flange_errors`` is replaced by the model's.
    protocol
        Cycles, warm-up, delta, speed, settle time, joints.
    sequences
        Absolute joint targets per sequence name; default :func:`sequences_at` the reference pose.
        Ignored when ``protocol.sequences`` is false.
    """
    spec = spec or WorldSpec()
    protocol = protocol or ProtocolSettings()
    session = _Session(model, spec, seed, protocol)
    try:
        ref = np.asarray(spec.reference_joints_deg, dtype=float)
        signs = away_signs(session.world, protocol.delta_deg)
        tests: dict[str, list[FloatArray]] = {}
        for j in protocol.joints:
            away = ref.copy()
            away[j - 1] += signs[j - 1] * protocol.delta_deg
            tests[f"J{j}"] = [away]
        if protocol.sequences:
            chosen: Mapping[str, Sequence[Sequence[float]]] = (
                sequences if sequences is not None else sequences_at(ref)
            )
            for name, poses in chosen.items():
                tests[name] = [np.asarray(t, dtype=float) for t in poses]
        points: dict[str, FloatArray] = {}
        for name, targets in tests.items():
            captured = []
            for cycle in range(protocol.warmup_cycles + protocol.cycles):
                for target in targets:
                    session.go(target)
                session.go(ref)
                if cycle >= protocol.warmup_cycles:
                    captured.append(session.capture())
            points[name] = np.asarray(captured, dtype=float)
        return ProtocolRun(points, {name: repeatability(p) for name, p in points.items()})
    finally:
        session.close()


def true_centers_mm(
    world: World,
    joints_deg: Sequence[Sequence[float]],
    moves: Sequence[int] | None = None,
    *,
    tool_point: bool = True,
) -> FloatArray:
    """The true positions (N, 2, mm) of captures made with the arm at ``joints_deg`` (truth, for tests).

    ``moves``: the arm's motion count at each capture (the twin's ``arm.moves``), which indexes the
    flange's Cartesian error; None leaves that error out (the kinematics of the attained joints alone).
    ``tool_point``: the repeatability plan's position (default), else ``center_mm`` (image origin).
    """
    if moves is not None and len(moves) != len(joints_deg):
        raise ValueError(f"moves must give one count per capture: {len(moves)} for {len(joints_deg)}")
    centres = [
        world.center_mm_at(tuple(q), move=None if moves is None else int(moves[i]), tool_point=tool_point)
        for i, q in enumerate(joints_deg)
    ]
    return np.asarray(centres, dtype=float)


__all__ = [
    "SEQUENCE_OFFSETS_DEG",
    "ProtocolRun",
    "ProtocolSettings",
    "away_signs",
    "sequences_at",
    "simulate_repeatability",
    "true_centers_mm",
]
