"""What ``station serve`` was given: the service's settings."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from station.worker import WORKER_NICE


@dataclass
class ServiceSettings:
    """What ``station serve`` was given."""

    sim: bool = False
    manual_prompts: bool = False
    config: Path | None = None
    data: Path | None = None
    database: str | None = field(default=None, repr=False)  # a URL may hold a password
    host: str = "127.0.0.1"
    port: int = 8465
    sim_options: dict[str, Any] = field(default_factory=dict)
    """Extra ``build_sim_station`` options (tests: seed, time scale)."""
    worker_nice: int = WORKER_NICE
    """The station worker's scheduling priority (``station.worker.WorkerSpec.nice``)."""
