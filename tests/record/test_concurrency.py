"""Readers never wait on the writer (SQLite WAL; PostgreSQL MVCC), across threads and processes."""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

from station.record import Record
from station.record._engine import BEGIN_OPTION
from station.record._schema import events, sessions
from tests.record.test_sessions import SNAPSHOT

READER = """
import sys
from pathlib import Path
from station.record import Record
url = None if sys.argv[2] == "-" else sys.argv[2]
with Record(Path(sys.argv[1]), url, busy_timeout_s=0) as rec:
    print(",".join(sorted(s.id for s in rec.list_sessions())), len(rec.events()), flush=True)
"""


def _hold_write_transaction(rec: Record, done: threading.Event, started: threading.Event) -> None:
    """Keep a write transaction open until ``done`` is set: a pending session and more rows than
    the writer's page cache holds, so that SQLite spills them to the database file (in rollback-journal
    mode that takes the EXCLUSIVE lock, which would shut every reader out)."""
    session_id = rec.list_sessions()[0].id
    with rec.engine.connect() as conn:
        if conn.dialect.name == "sqlite":
            conn.exec_driver_sql("PRAGMA cache_size=5")
            conn.commit()
        conn = conn.execution_options(**{BEGIN_OPTION: "IMMEDIATE"})
        with conn.begin() as tx:
            row = {**SNAPSHOT, "kind": "pending", "state": "idle", "station": "default"}
            now = rec.get_session(session_id).created_at
            conn.execute(sessions.insert().values(id="ffffffffffff", created_at=now, updated_at=now, **row))
            pad = {"pad": "x" * 4000}
            rows = [
                {"session_id": session_id, "seq": 100 + i, "time": now, "type": "pad", "data": pad}
                for i in range(300)
            ]
            conn.execute(events.insert(), rows)
            started.set()
            done.wait(60)
            tx.rollback()


def test_reader_reads_while_a_write_transaction_is_open(tmp_path: Path, record_url: str | None) -> None:
    writer = Record(tmp_path / "data", record_url)
    committed = writer.create_session("validation", **SNAPSHOT)
    writer.add_event(committed.id, "state", {"state": "running"})
    done, started = threading.Event(), threading.Event()
    holder = threading.Thread(target=_hold_write_transaction, args=(writer, done, started))
    holder.start()
    try:
        assert started.wait(60)
        # another thread with its own connections, failing at once on any lock (busy timeout 0)
        seen: list[object] = []

        def read() -> None:
            try:
                with Record(tmp_path / "data", record_url, busy_timeout_s=0) as reader:
                    seen.append([s.id for s in reader.list_sessions()])
                    seen.append(len(reader.events()))
            except BaseException as exc:  # noqa: BLE001 - reported by the test body
                seen.append(exc)

        thread = threading.Thread(target=read)
        thread.start()
        thread.join(60)
        assert not thread.is_alive(), "the reader thread waited on the writer"
        assert seen == [[committed.id], 1]
        # and another process
        out = subprocess.run(
            [sys.executable, "-c", READER, str(tmp_path / "data"), record_url or "-"],
            capture_output=True,
            text=True,
            timeout=120,
            check=True,
        ).stdout.split()
        assert out == [committed.id, "1"]
    finally:
        done.set()
        holder.join(60)
        writer.close()


def test_sqlite_is_in_wal_mode_with_foreign_keys(tmp_path: Path) -> None:
    with Record(tmp_path) as rec, rec.engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        assert conn.exec_driver_sql("PRAGMA busy_timeout").scalar() == 30000


def test_readers_follow_a_committing_writer(tmp_path: Path, record_url: str | None) -> None:
    """A reader polling events while the writer commits sees a growing, gap-free sequence."""
    with Record(tmp_path / "d", record_url) as writer, Record(tmp_path / "d", record_url) as reader:
        s = writer.create_session("repeatability", **SNAPSHOT)
        finished = threading.Event()
        errors: list[BaseException] = []

        def write() -> None:
            try:
                for i in range(200):
                    writer.add_event(s.id, "progress", {"done": i})
            except BaseException as exc:  # noqa: BLE001 - reported by the test body
                errors.append(exc)
            finally:
                finished.set()

        thread = threading.Thread(target=write)
        thread.start()
        seen: list[int] = []
        last_id = 0
        while True:
            end = finished.is_set()
            batch = reader.events(s.id, after_id=last_id)
            seen.extend(e.seq for e in batch)
            last_id = batch[-1].id if batch else last_id
            if end and not batch:
                break
        thread.join(60)
        assert errors == []
        assert seen == list(range(1, 201))
