"""A session's files as the service serves them: its outcome, its report folder (written when first
asked for, or again after the session changed), its export as a zip, and the import of one.

The routers get it as a FastAPI dependency (``api._deps.session_files``); it reads and writes the
record and the data directory, so that no router reaches into them.
"""

from __future__ import annotations

import io
import tempfile
import threading
import zipfile
from collections.abc import Callable
from pathlib import Path

from station.record import ArchiveLimits, Record, SessionRow
from station.reporting import write_report
from station.resources import SessionOutcome, report_document
from station.runner import ACTIVE_STATES
from station.worker import ConflictError


class SessionFiles:
    """The outcome, report, export and import of the record's sessions; ``on_import`` is called after a
    session was imported (the service's cached reads are then stale)."""

    def __init__(self, record: Record, on_import: Callable[[], None]) -> None:
        self.record = record
        self._on_import = on_import
        self._report_lock = threading.Lock()

    def results(self, session_id: str) -> SessionOutcome:
        """``station run --json``'s object for the session."""
        return SessionOutcome.of(self.record.get_session(session_id))

    def report_dir(self, session_id: str) -> Path:
        """The session's report folder, written now if absent or older than the session's last change."""
        row = self.record.get_session(session_id)
        if row.state in ACTIVE_STATES:
            raise ConflictError(f"session {row.id} is {row.state}: its report is written once it has ended")
        folder = self.record.data_dir / "reports" / row.id
        stamp = folder / ".written"
        # one writer at a time in this process, so that a report is written once: the second of two
        # pages asking at once finds it written (each file's temporary name is unique, so writers in
        # other processes, such as ``station report``, cannot collide with this one either)
        with self._report_lock:
            if not stamp.exists() or stamp.read_text() != row.updated_at.isoformat():
                write_report(report_document(row), folder)
                stamp.write_text(row.updated_at.isoformat())
        return folder

    def export_zip(self, session_id: str) -> tuple[str, bytes]:
        """The session's export folder, zipped; with the record's own id of the session."""
        row = self.record.get_session(session_id)
        with tempfile.TemporaryDirectory() as tmp:
            out = self.record.export_session(row.id, Path(tmp) / row.id)
            buf = io.BytesIO()
            with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
                for path in sorted(out.rglob("*")):
                    if path.is_file():
                        zf.write(path, Path(row.id) / path.relative_to(out))
            return row.id, buf.getvalue()

    def import_zip(self, data: bytes, *, max_bytes: int) -> SessionRow:
        """Import an uploaded zip of an export: the record's one import path (``station import`` too),
        with the upload's caps; the record's ArchiveRefusedError (a 422 at the API) names what is refused."""
        row = self.record.import_archive(io.BytesIO(data), limits=ArchiveLimits(max_total_bytes=max_bytes))
        self._on_import()
        return row
