"""What a controller self-test found: one :class:`CheckResult` per check, and the whole
:class:`SelftestResult` (printed by ``station robot selftest``; ``--json``: its ``to_dict()``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

__all__ = ["CHECK_NAMES", "CHECK_STATES", "CheckResult", "CheckState", "SelftestResult"]

CheckState = Literal["passed", "failed", "inconclusive", "not_run"]
CHECK_STATES: tuple[CheckState, ...] = ("passed", "failed", "inconclusive", "not_run")
"""``passed``; ``failed`` (the controller differs from what the station assumes); ``inconclusive`` (the
check could not be made here: its ``summary`` says what to do); ``not_run`` (an earlier check left the arm
latched or elsewhere)."""

CHECK_NAMES = ("directions", "world", "ready", "halt")
"""The checks, in the order they run: each joint's direction against the camera's view, WORLD against the
station's arm model at N poses, the ready pose, the halt key at low speed (last: it latches the stop)."""


@dataclass(frozen=True)
class CheckResult:
    """One check: its ``name`` (``CHECK_NAMES``), ``state`` (``CHECK_STATES``), a one-line ``summary``
    (on anything but ``passed``, what to do), and its figures (``details``, JSON-ready)."""

    name: str
    state: CheckState
    summary: str
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "state": self.state, "summary": self.summary, "details": self.details}


@dataclass(frozen=True)
class SelftestResult:
    """The controller's self-test: ``passed`` only when every check passed; ``checks`` in order;
    ``identity`` the robot's as it reports it (a later session compares it); ``latched``: the stop latch
    is set when the test ends (the halt check sets it on purpose) and must be acknowledged at the station
    before the arm moves again; ``start_joints_deg`` where the arm was when the test began."""

    checks: tuple[CheckResult, ...]
    identity: dict[str, str | None]
    latched: bool
    start_joints_deg: tuple[float, ...]
    started_at: str
    finished_at: str

    @property
    def passed(self) -> bool:
        return all(c.state == "passed" for c in self.checks)

    def check(self, name: str) -> CheckResult:
        """The check called ``name`` (KeyError when it is not in this result)."""
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(f"no check {name!r} in this self-test (it has {[c.name for c in self.checks]})")

    def to_dict(self) -> dict[str, Any]:
        return {
            "passed": self.passed,
            "checks": [c.to_dict() for c in self.checks],
            "identity": dict(self.identity),
            "latched": self.latched,
            "start_joints_deg": list(self.start_joints_deg),
            "started_at": self.started_at,
            "finished_at": self.finished_at,
        }
