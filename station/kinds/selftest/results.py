"""The ``selftest`` kind's results: the controller self-test's checks (``station.selftest``), the robot's
identity it holds for, and the session's gates."""

from __future__ import annotations

from typing import Any

from pydantic import Field

from station.plans._results import Check, ResultsModel


class ControllerCheck(ResultsModel):
    """One check of the self-test: ``state`` passed, failed, inconclusive or not_run; ``summary`` says what
    to do on anything but passed; ``details`` its figures."""

    name: str
    state: str
    summary: str
    details: dict[str, Any] = Field(default_factory=dict)


class SelftestResults(ResultsModel):
    passed: bool
    identity: dict[str, str | None] = Field(default_factory=dict)
    latched: bool = False
    start_joints_deg: list[float] = Field(default_factory=list)
    started_at: str | None = None
    finished_at: str | None = None
    controller_checks: list[ControllerCheck] = Field(default_factory=list)
    checks: list[Check] = Field(default_factory=list)
