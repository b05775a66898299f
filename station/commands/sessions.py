"""``station sessions``, ``station report ID``, ``station export ID OUT``, ``station import DIR``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from station.commands import SubParsers
from station.commands.run import add_record_options
from station.record import Record, RecordError, SessionRow, lock_holder
from station.reporting import ReportError
from station.resources import SessionSummary, dumps
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

    i = sub.add_parser("import", help="import a session folder written by station export")
    i.add_argument("folder", metavar="DIR")
    add_record_options(i)
    i.set_defaults(func=run_import)


def _open(args: argparse.Namespace) -> Record:
    return open_record(args.data, args.database)


def _reconciled(record: Record) -> None:
    """Sessions left active by a dead process show as interrupted (only when no runner holds the lock)."""
    from station.record import SessionLockError, station_lock
    from station.runner import reconcile

    if lock_holder(Path(record.data_dir)) is not None:
        return
    try:
        with station_lock(Path(record.data_dir), "station sessions"):
            reconcile(record)
    except SessionLockError:
        return


def run_sessions(args: argparse.Namespace) -> int:
    try:
        with _open(args) as record:
            _reconciled(record)
            rows = record.list_sessions()
    except RecordError as exc:
        print(f"station sessions: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(dumps([SessionSummary.of(r) for r in rows]))
        return 0
    from station.report import table

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


def report_document(row: SessionRow) -> dict[str, Any]:
    """What ``station.reporting.write_report`` takes: the session object with identities and software."""
    return {**session_json(row), "identities": row.identities, "software": row.software}


def write_session_report(
    session: str, data: str | Path | None, database: str | None, out: str | Path | None = None
) -> ReportFiles:
    """Write session ``session``'s report (default folder: DATA/reports/ID)."""
    from station.reporting import write_report

    with open_record(data, database) as record:
        row = record.get_session(session)
        folder = Path(out) if out else Path(record.data_dir) / "reports" / row.id
        return write_report(report_document(row), folder)


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
        with _open(args) as record:
            out = record.export_session(record.get_session(args.session).id, Path(args.out))
    except (RecordError, OSError) as exc:
        print(f"station export: {exc}", file=sys.stderr)
        return 1
    print(out)
    return 0


def run_import(args: argparse.Namespace) -> int:
    try:
        with _open(args) as record:
            row = record.import_session(Path(args.folder))
    except (RecordError, OSError) as exc:
        print(f"station import: {exc}", file=sys.stderr)
        return 1
    print(row.id)
    return 0
