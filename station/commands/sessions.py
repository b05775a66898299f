"""``station sessions``, ``station report ID``, ``station export ID OUT``, ``station import DIR|ZIP``.

``sessions``, ``report`` and ``export`` only read the record: it is opened read-only (never created,
migrated, locked or written; they work on a full disk and in a read-only data directory). ``report``
writes the report's files, and only those: into the session's report folder (``DATA/reports/ID``,
where the service keeps it too) or into ``--out DIR``. ``import`` takes an export folder or a zip of
one, through the record's one import path (the service's ``POST /api/v1/sessions/import`` too).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from station.commands._parsing import SubParsers, add_record_options
from station.record import (
    ImportRefusedError,
    NoRecordError,
    Record,
    RecordError,
    SessionRow,
    station_in_use,
)
from station.reporting import ReportError
from station.resources import SessionSummary, dumps, report_document
from station.session import open_record

if TYPE_CHECKING:
    from station.reporting import ReportFiles


def session_json(row: SessionRow) -> dict[str, Any]:
    """The session object of ``station sessions --json``: :class:`station.resources.SessionSummary`
    (the API's session resource is the same model with the live progress)."""
    return SessionSummary.of(row).model_dump()


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "sessions", help="list the recorded sessions", description="List the record's sessions."
    )
    p.add_argument("--json", action="store_true", help="one JSON array of session objects")
    add_record_options(p)
    p.set_defaults(func=run_sessions)

    r = sub.add_parser(
        "report",
        help="write a session's tables and figures (PNG, SVG, HTML)",
        description="Write the seed's tables and figures for session ID, and one HTML report.",
    )
    r.add_argument("session", metavar="ID")
    r.add_argument("--out", metavar="DIR", help="where to write (default: DATA/reports/ID)")
    add_record_options(r)
    r.set_defaults(func=run_report)

    e = sub.add_parser("export", help="export a session as a self-contained folder (JSON, CSV, images)")
    e.add_argument("session", metavar="ID")
    e.add_argument("out", metavar="OUT")
    add_record_options(e)
    e.set_defaults(func=run_export)

    i = sub.add_parser(
        "import",
        help="import a session folder written by station export (or a zip of one, e.g. export.zip)",
    )
    i.add_argument("folder", metavar="DIR|ZIP")
    add_record_options(i)
    i.set_defaults(func=run_import)


def _open(args: argparse.Namespace, *, read_only: bool = False) -> Record:
    return open_record(args.data, args.database, read_only=read_only)


def shown_sessions(record: Record, *, own_record: bool) -> list[SessionRow]:
    """The record's sessions, newest first, as they stand: on a station's own record (SQLite in its
    data directory), a session left active while no process holds or is finishing on the station was
    left by a dead process and shows ``interrupted`` (as the next session start will record it). Reads
    only: nothing is written and no lock is taken (a session may start meanwhile)."""
    from station.runner import ACTIVE_STATES

    rows = record.list_sessions()
    if not own_record or not any(r.state in ACTIVE_STATES for r in rows):
        return rows
    if station_in_use(Path(record.data_dir)):
        return rows
    out = []
    for r in rows:
        if r.state in ACTIVE_STATES:
            r = record.get_session(r.id)  # read after the lock: one that has just ended says so now
            if r.state in ACTIVE_STATES:
                r = dataclasses.replace(r, state="interrupted")
        out.append(r)
    return out


def run_sessions(args: argparse.Namespace) -> int:
    try:
        with _open(args, read_only=True) as record:
            rows = shown_sessions(record, own_record=args.database is None)
    except NoRecordError as exc:
        print(f"station sessions: {exc}", file=sys.stderr)
        rows = []
    except RecordError as exc:
        print(f"station sessions: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(dumps([SessionSummary.of(r) for r in rows]))
        return 0
    from station.text_tables import table

    print(
        table(
            ["ID", "KIND", "STATE", "CREATED", "ERROR"],
            [
                [r.id, r.kind, r.state, r.created_at.strftime("%Y-%m-%d %H:%M:%S"), (r.error or "")[:60]]
                for r in rows
            ],
        )
    )
    return 0


def write_session_report(
    session: str, data: str | Path | None, database: str | None, out: str | Path | None = None
) -> ReportFiles:
    """Write session ``session``'s report into ``out``, else its report folder (``DATA/reports/ID``).
    The record is only read."""
    from station.reporting import write_report

    with open_record(data, database, read_only=True) as record:
        row = record.get_session(session)
        folder = Path(out) if out else Path(record.data_dir) / "reports" / row.id
        try:
            return write_report(report_document(row), folder)
        except ReportError as exc:
            if out:
                raise
            raise ReportError(f"{exc}; give --out DIR to write the report elsewhere") from exc


def run_report(args: argparse.Namespace) -> int:
    try:
        files = write_session_report(args.session, args.data, args.database, args.out)
    except (RecordError, OSError, ReportError) as exc:
        print(f"station report: {exc}", file=sys.stderr)
        return 1
    for name, text in files.tables.items():
        if name != "positions":  # the 40-row table is in the HTML report
            print(f"{text}\n")
    print(f"report: {files.html}")
    for f in files.figures:
        print(f"figure: {f}")
    return 0


def run_export(args: argparse.Namespace) -> int:
    try:
        with _open(args, read_only=True) as record:
            out = record.export_session(record.get_session(args.session).id, Path(args.out))
    except (RecordError, OSError) as exc:
        print(f"station export: {exc}", file=sys.stderr)
        return 1
    print(out)
    return 0


def run_import(args: argparse.Namespace) -> int:
    source = Path(args.folder)
    if not source.exists():
        print(f"station import: {source}: no such folder or zip file", file=sys.stderr)
        return 2
    try:
        with _open(args) as record:
            row = record.import_path(source)
    except ImportRefusedError as exc:
        print(f"station import: refused: {exc}", file=sys.stderr)
        return 1
    except (RecordError, OSError) as exc:
        print(f"station import: {exc}", file=sys.stderr)
        return 1
    print(row.id)
    return 0
