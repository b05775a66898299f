"""Sessions in a process of their own: the station's devices and its session runner, away from a front
end's interpreter.

A front end that serves many clients (``station serve``) spends its interpreter's time on requests; a
session runner sharing that interpreter waits for it at every hand-over of the GIL (a serial reply, a
frame, a record write), and the arm's cycle stretches with the number of clients. So the service keeps
the HTTP side and the record's reads, and a *station worker* process owns everything that drives
hardware:

- :class:`~station.worker.host.SessionHost` (the worker side, ``host.py``) builds the devices once (a
  configuration's, or the simulated station's), creates and runs one
  :class:`~station.runner.SessionRunner` at a time in a thread, and answers the operator prompts
  through the station's :class:`~station.prompts.PromptBroker`;
- :class:`~station.worker.client.WorkerClient` (the service side, ``client.py``) starts the worker,
  calls it (``create``, ``act``, ``confirm`` ...) and mirrors what it reports: the runner's events
  with its state and progress, the operator prompt that is open, and the worker's log records
  (re-emitted through the front end's own loggers). Reads of the mirror never cross the process boundary.

Both processes open the same record (SQLite in WAL mode, or the configured server): the runner writes
it, the front end reads it. An event reaches the front end after the runner has committed it, so a
front end that sees a ``state`` event reads the new row.

The worker's exceptions come back as the same types (a ``PreflightError`` is a ``PreflightError``).
The worker never outlives its front end: it ignores Ctrl-C (the front end shuts it down in order), and
when its pipe closes or it gets SIGTERM it aborts the running session (the robot stopped through its
latched ``stop()``), records it as ``interrupted`` and closes the devices.

The pipe between them and how exceptions and log records cross it is ``_transport.py``; the worker
process's entry point ``_process.py``; what both sides share ``_common.py``.
"""

from station.worker._common import (
    DEVICE_NAMES,
    NO_REFERENCE,
    RECORD_RETRY_S,
    START_TIMEOUT_S,
    WORKER_NICE,
    ConflictError,
    NotAvailableError,
    RunnerStatus,
    StationInfo,
    WorkerError,
    WorkerSpec,
)
from station.worker._process import main, worker_main
from station.worker.client import WorkerClient
from station.worker.host import SessionHost

__all__ = [
    "DEVICE_NAMES",
    "NO_REFERENCE",
    "RECORD_RETRY_S",
    "START_TIMEOUT_S",
    "WORKER_NICE",
    "ConflictError",
    "NotAvailableError",
    "RunnerStatus",
    "SessionHost",
    "StationInfo",
    "WorkerClient",
    "WorkerError",
    "WorkerSpec",
    "main",
    "worker_main",
]
