"""The self-test's halt check: the halt key at low speed (see ``station.selftest._checks``' notes).

A slow move of joint ``HALT_JOINT`` is timed unhalted, then the same move is halted (``stop()``: the halt
key) after ``HALT_FRACTION`` of that time, from another thread, as a session's stop would be. The arm
must stop short of its target, be still, and stop within ``STOP_ANGLE_DEG`` of where a uniform motion
over the timed move would have been when the key was sent. The stop stays latched: a person at the
station acknowledges it before the arm moves again.
"""

from __future__ import annotations

import math
import threading

from station.devices import MotionStoppedError
from station.selftest._result import CheckResult
from station.selftest._rig import HALT_SPEED_PCT, SelftestRig, free, offset

__all__ = ["HALT_FRACTION", "HALT_JOINT", "HALT_MOVE_DEG", "HALT_SPEED_PCT", "STOP_ANGLE_DEG", "check_halt"]

HALT_JOINT = 6
"""The joint the halt is tested on: the wrist's roll, the smallest sweep of the arm."""
HALT_MOVE_DEG = 10.0
HALT_FRACTION = 0.4
"""The halt key is sent after this fraction of the unhalted move's time."""
STOP_ANGLE_DEG = 1.0
"""The stated stopping angle: the joint stops within this of where it was when the key was sent."""


def check_halt(rig: SelftestRig) -> CheckResult:
    """The halt key at low speed (see the module notes); leaves the stop latched."""
    start = rig.commanded()
    axis = HALT_JOINT
    delta = HALT_MOVE_DEG if free(rig.robot, offset(start, axis, HALT_MOVE_DEG), start) else -HALT_MOVE_DEG
    rig.robot.check_move(offset(start, axis, delta), start_deg=start)
    rig.speed(rig.halt_speed_pct)
    t0 = rig.clock()
    rig.robot.move_joint(axis, delta)
    timed_s = rig.clock() - t0
    rig.robot.move_joint(axis, -delta)
    begin = rig.robot.where().joints_deg[axis - 1]
    failure: list[BaseException] = []
    done = threading.Event()

    def halted_move() -> None:
        try:
            rig.robot.move_joint(axis, delta)
        except BaseException as exc:  # noqa: BLE001 - handed to the checking thread
            failure.append(exc)
        finally:
            done.set()

    worker = threading.Thread(target=halted_move, name="selftest halt", daemon=True)
    t1 = rig.clock()
    worker.start()
    if done.wait(HALT_FRACTION * timed_s):
        return CheckResult(
            "halt",
            "inconclusive",
            f"the move ended in {rig.clock() - t1:.3f} s, before the halt was due: too short a move to halt"
            " (the host's reply time is long against it)",
            {"timed_s": round(timed_s, 4)},
        )
    rig.robot.stop()
    halt_s = rig.clock() - t1
    worker.join(10.0 + 3.0 * timed_s)
    if worker.is_alive():
        return CheckResult(
            "halt",
            "failed",
            f"the halted move had not returned {10.0 + 3.0 * timed_s:.0f} s after the halt key: press the"
            " E-stop, look at the arm, and check the controller's link and its halt (DIALECT.md, still"
            " assumed 2)",
            {"timed_s": round(timed_s, 4), "halt_after_s": round(halt_s, 4)},
        )
    rig.robot.wait_settled(10.0)
    end = rig.robot.where().joints_deg[axis - 1]
    travelled = (end - begin) * math.copysign(1.0, delta)
    expected_at_key = abs(delta) * halt_s / timed_s
    coasting = travelled - expected_at_key
    details = {
        "joint": axis,
        "move_deg": delta,
        "speed_pct": rig.halt_speed_pct,
        "timed_s": round(timed_s, 4),
        "halt_after_s": round(halt_s, 4),
        "travelled_deg": round(travelled, 4),
        "uniform_at_key_deg": round(expected_at_key, 4),
        "stopping_angle_deg": round(coasting, 4),
        "stated_stop_angle_deg": STOP_ANGLE_DEG,
        "error": None if not failure else str(failure[0]),
    }
    if not failure or not isinstance(failure[0], MotionStoppedError) or travelled >= abs(delta) - 0.05:
        return CheckResult(
            "halt",
            "failed",
            "the halt key did not stop the move (it reached its target or ended otherwise): do not run"
            " unattended; check ShellProfile.stop_sequence (DIALECT.md, still assumed 2) and rely on the"
            " E-stop",
            details,
        )
    if travelled < 0.05:
        return CheckResult(
            "halt",
            "inconclusive",
            "the arm had not started when it was halted: run the self-test again",
            details,
        )
    if coasting > STOP_ANGLE_DEG:
        return CheckResult(
            "halt",
            "failed",
            f"the joint went on {coasting:.2f} deg after the halt key, more than {STOP_ANGLE_DEG:g} deg:"
            " check the controller's halt (DIALECT.md, still assumed 2) and rely on the E-stop",
            details,
        )
    return CheckResult(
        "halt",
        "passed",
        f"halted at {rig.halt_speed_pct:g} %, within {max(coasting, 0.0):.2f} deg of where it was when the"
        f" key was sent (stated {STOP_ANGLE_DEG:g} deg)",
        details,
    )
