"""What both sides of the station worker share: its errors, its start specification, what it reports
(the station's facts, the runner's status) and its constants."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from station.runner import (
    Progress,
    SessionError,
    SessionState,
)

log = logging.getLogger(__name__)


WORKER_NICE = -10

START_TIMEOUT_S = 120.0
RECORD_RETRY_S = 1.0


class ConflictError(SessionError):
    """The request does not fit the session's or the station's state (the API answers it with a 409)."""


class NotAvailableError(SessionError):
    """The station has no such device or feature in this configuration (a 409 at the API)."""


class WorkerError(NotAvailableError):
    """The station's worker process is not there (it failed to start, or died); restart the service."""


@dataclass(frozen=True)
class WorkerSpec:
    """What the worker builds: the record's place and the station (a configuration, or the sim)."""

    sim: bool = False
    manual_prompts: bool = False
    config: Path | None = None
    data: Path | None = None
    database: str | None = field(default=None, repr=False)  # a URL may hold a password
    sim_options: dict[str, Any] = field(default_factory=dict)
    log_level: int = logging.INFO
    """The worker's log records at this level and above reach the front end's loggers (which filter them
    again by their own levels)."""
    nice: int = WORKER_NICE
    """The worker's scheduling priority (a nice value; negative is preferred): when the machine is short
    of CPU, the clients wait, not the arm. Lowering it needs the right to (root, or CAP_SYS_NICE, e.g.
    systemd's ``LimitNICE=``); without it the worker keeps the front end's priority."""


@dataclass(frozen=True)
class StationInfo:
    """The station the worker built: which devices it has, their identities, its configuration."""

    devices: tuple[str, ...]
    identities: dict[str, Any]
    name: str | None
    config_snapshot: dict[str, Any] | None
    nice: int = 0
    """The worker's scheduling priority (nice value) as it runs."""


@dataclass(frozen=True)
class RunnerStatus:
    """The worker's latest session as of its latest event."""

    session_id: str
    kind: str
    state: SessionState
    progress: Progress
    error: str | None = None
    """Set when the session failed in a way its runner could not record (the record unreachable, an
    error of the worker's own): the front end shows it ``failed`` with this reason meanwhile."""


DEVICE_NAMES = ("robot", "camera", "table", "distance_sensor")
NO_REFERENCE = (
    "this station has no robot with a reference pose (configure [robot] with reference_joints_deg, or start"
    " the service with --sim)"
)
