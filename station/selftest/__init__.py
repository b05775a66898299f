"""The controller self-test (issue 23, item 3), the driver-level checks over the
:class:`station.devices.Robot` interface and the camera: each joint's direction against the camera's view,
WORLD against the station's arm model at N poses, the ready pose, and the halt key at low speed
(``_checks``; the view's maths ``_view``; the result ``_result``). ``station robot --config F selftest``
prints its result. A session kind recording it with the station's identity is the session code's.
"""

from station.selftest._checks import (
    MIN_COSINE,
    RATIO_RANGE,
    READY_TOLERANCE_DEG,
    TARGET_SIGNAL_PX,
    WORLD_OFFSETS_DEG,
    WORLD_TOLERANCE_DEG,
    WORLD_TOLERANCE_MM,
    check_directions,
    check_ready,
    check_world,
    run_selftest,
)
from station.selftest._halt import HALT_FRACTION, HALT_JOINT, HALT_MOVE_DEG, STOP_ANGLE_DEG, check_halt
from station.selftest._result import CHECK_NAMES, CHECK_STATES, CheckResult, CheckState, SelftestResult
from station.selftest._rig import HALT_SPEED_PCT, SelftestRig, selftest_rig
from station.selftest._view import LEVER_PX, agreement, predicted_signal, signal, wrap_cross_deg

__all__ = [
    "CHECK_NAMES",
    "CHECK_STATES",
    "HALT_FRACTION",
    "HALT_JOINT",
    "HALT_MOVE_DEG",
    "HALT_SPEED_PCT",
    "LEVER_PX",
    "MIN_COSINE",
    "RATIO_RANGE",
    "READY_TOLERANCE_DEG",
    "STOP_ANGLE_DEG",
    "TARGET_SIGNAL_PX",
    "WORLD_OFFSETS_DEG",
    "WORLD_TOLERANCE_DEG",
    "WORLD_TOLERANCE_MM",
    "CheckResult",
    "CheckState",
    "SelftestResult",
    "SelftestRig",
    "agreement",
    "check_directions",
    "check_halt",
    "check_ready",
    "check_world",
    "predicted_signal",
    "run_selftest",
    "selftest_rig",
    "signal",
    "wrap_cross_deg",
]
