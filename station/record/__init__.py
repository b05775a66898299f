"""The station's durable record: sessions, steps, events, captures (PNG files), measurements.

SQLAlchemy Core over SQLite by default (``DATA_DIR/record.sqlite``, WAL mode so that readers never wait
on the runner) or any SQLAlchemy URL (PostgreSQL for a lab whose stations share one record); the
schema is kept by Alembic migrations shipped in this package and applied when a record is opened.
Images are lossless PNG files beside the database, written atomically before their row is committed.
``station_lock`` keeps one session at a time per station, across processes.
"""

from station.record._errors import (
    ArchiveRefusedError,
    ImportRefusedError,
    NoRecordError,
    RecordError,
    RecordNotFoundError,
    RecordUnavailableError,
    RecordWriteError,
    SessionLockError,
)
from station.record._format import capture_path
from station.record._json import MAX_POINTS, params_hash, strip_point_arrays
from station.record._lock import StationLock, lock_holder, station_in_use, station_lock
from station.record._record import Record
from station.record._rows import SESSION_STATES, CaptureRow, EventRow, MeasurementRow, SessionRow, StepRow
from station.record._sources import ArchiveLimits

__all__ = [
    "MAX_POINTS",
    "SESSION_STATES",
    "ArchiveLimits",
    "ArchiveRefusedError",
    "CaptureRow",
    "EventRow",
    "ImportRefusedError",
    "MeasurementRow",
    "NoRecordError",
    "Record",
    "RecordError",
    "RecordNotFoundError",
    "RecordUnavailableError",
    "RecordWriteError",
    "SessionLockError",
    "SessionRow",
    "StationLock",
    "StepRow",
    "capture_path",
    "lock_holder",
    "params_hash",
    "station_in_use",
    "station_lock",
    "strip_point_arrays",
]
