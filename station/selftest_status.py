"""The controller self-test's standing (issue 23, item 3): the latest ``selftest`` session of the
controller a station has now, attached to every later session and published by ``/api/v1/station``.

A self-test holds for the controller it ran on until that controller's identity changes: its model, serial
and firmware as the robot reports them (``DeviceIdentity``; the port it is reached on is not the
controller's identity). A session of a station with a robot carries ``results.selftest`` = ``{session_id,
passed, when}`` of the latest self-test of its controller (``None`` when there is none) and a ``warn``
check ``selftest`` that fails when that self-test failed or is missing, with what to do.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict
from datetime import datetime
from typing import Any

from station.plans._gates import Check
from station.record import Record

__all__ = [
    "IDENTITY_KEYS",
    "KIND",
    "attach_selftest",
    "attach_to_session",
    "controller_key",
    "latest_selftest",
    "robot_identity",
    "selftest_check",
]

KIND = "selftest"
IDENTITY_KEYS = ("model", "serial", "firmware")
"""What names a controller: a change in any of them asks for a new self-test."""
FINISHED = ("succeeded", "failed")
RUN_IT = "run the controller self-test (station run selftest, or the page's Robot panel)"


def controller_key(identity: Mapping[str, Any] | None) -> tuple[str | None, ...] | None:
    """The controller's identity as compared (None: no robot identity)."""
    if not isinstance(identity, Mapping):
        return None
    return tuple(None if identity.get(k) is None else str(identity.get(k)) for k in IDENTITY_KEYS)


def latest_selftest(record: Record, robot_identity: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """``{session_id, passed, when}`` of the latest finished self-test of the controller ``robot_identity``
    names (None: no such self-test on record, or no identity to compare)."""
    key = controller_key(robot_identity)
    if key is None:
        return None
    for s in record.list_sessions(KIND):
        if s.state not in FINISHED or not s.results:
            continue
        if controller_key(s.results.get("identity") or s.identities.get("robot")) != key:
            continue
        when = s.results.get("finished_at")
        if not isinstance(when, str):
            when = s.updated_at.isoformat() if isinstance(s.updated_at, datetime) else None
        return {"session_id": s.id, "passed": bool(s.results.get("passed")), "when": when}
    return None


def selftest_check(latest: Mapping[str, Any] | None) -> Check:
    """The ``warn`` check a session carries about its controller's self-test."""
    if latest is None:
        return Check(
            "selftest", False, None, 0.0, "warn", f"no self-test of this controller on record: {RUN_IT}"
        )
    if not latest.get("passed"):
        return Check(
            "selftest",
            False,
            0.0,
            1.0,
            "warn",
            f"the latest self-test of this controller (session {latest.get('session_id')}, "
            f"{latest.get('when')}) did not pass: see its results, put right what it names, then {RUN_IT}",
        )
    return Check(
        "selftest",
        True,
        1.0,
        1.0,
        "warn",
        f"the controller passed its self-test (session {latest.get('session_id')}, {latest.get('when')})",
    )


def attach_selftest(
    results: dict[str, Any], record: Record, robot_identity: Mapping[str, Any] | None
) -> dict[str, Any]:
    """``results`` with ``selftest`` (the latest self-test of the controller, or None) and its check."""
    latest = latest_selftest(record, robot_identity)
    checks = [
        c for c in results.get("checks", []) if not (isinstance(c, Mapping) and c.get("name") == "selftest")
    ]
    return {**results, "selftest": latest, "checks": [*checks, selftest_check(latest).to_json()]}


def attach_to_session(
    results: dict[str, Any], record: Record, session_id: str, robot_identity: Mapping[str, Any] | None
) -> dict[str, Any]:
    """A session's results with its controller's self-test attached (:func:`attach_selftest`);
    ``robot_identity``: the robot's as it reported it once connected (None: a station without a robot,
    or an offline session: the results unchanged). A self-test's own results are left as they are."""
    if robot_identity is None or record.get_session(session_id).kind == KIND:
        return results
    return attach_selftest(results, record, robot_identity)


def robot_identity(devices: Any) -> dict[str, Any] | None:
    """The identity a station's robot reports (``StationDevices.robot``; None without one)."""
    robot = getattr(devices, "robot", None)
    return None if robot is None else asdict(robot.identity())
