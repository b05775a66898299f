"""Fixtures of the record tests: each runs on SQLite and on a real PostgreSQL server.

The PostgreSQL server is Debian's (``/usr/lib/postgresql/*/bin``), started once per test process in a
temporary directory: ``initdb`` and ``pg_ctl`` refuse to run as root, so as root they run as the
``postgres`` user in a directory it owns. The server listens on a unix socket in that directory only
(no TCP port to collide with), and every test gets a fresh schema (its own search path). Without
PostgreSQL the tests skip, except under ``CI=true`` where they fail (CI installs ``postgresql``:
tools/apt-packages.txt).
"""

from __future__ import annotations

import contextlib
import itertools
import os
import pwd
import shutil
import subprocess
import tempfile
from collections.abc import Callable, Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

from station.record import Record
from tests.conftest import needs_system

PG_USER = "station"
PG_HINT = "Debian package postgresql"


def _pg_bin() -> Path | None:
    found = sorted(Path("/usr/lib/postgresql").glob("*/bin/initdb"), key=lambda p: int(p.parent.parent.name))
    return found[-1].parent if found else None


class PostgresServer:
    """A throw-away PostgreSQL cluster listening on a unix socket in its own directory."""

    def __init__(self, bin_dir: Path) -> None:
        self.bin = bin_dir
        self.root = Path(tempfile.mkdtemp(prefix="station-pg-"))
        self.data = self.root / "data"
        self.run_as: dict[str, Any] = {}
        if os.geteuid() == 0:
            pw = pwd.getpwnam("postgres")
            os.chown(self.root, pw.pw_uid, pw.pw_gid)
            self.run_as = {"user": pw.pw_uid, "group": pw.pw_gid, "extra_groups": []}
        self._names = itertools.count(1)

    def _run(self, *args: str) -> None:
        done = subprocess.run(
            args, cwd=self.root, capture_output=True, text=True, timeout=120, check=False, **self.run_as
        )
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(args)} failed ({done.returncode}): {done.stderr or done.stdout}")

    def start(self) -> None:
        self._run(
            str(self.bin / "initdb"), "-D", str(self.data), "-U", PG_USER, "--auth=trust",
            "--encoding=UTF8", "--no-locale", "--no-sync",
        )  # fmt: skip
        self.resume()

    def resume(self) -> None:
        """Start the cluster's server (again, after :meth:`halt`)."""
        options = f"-c listen_addresses='' -k {self.root} -c fsync=off -c full_page_writes=off"
        self._run(
            str(self.bin / "pg_ctl"), "-D", str(self.data), "-l", str(self.root / "server.log"),
            "-o", options, "-w", "-t", "60", "start",
        )  # fmt: skip

    def halt(self) -> None:
        """Stop the server at once, as a crash would (``pg_ctl stop -m immediate``); the cluster stays."""
        self._run(str(self.bin / "pg_ctl"), "-D", str(self.data), "-m", "immediate", "-w", "stop")

    def stop(self) -> None:
        with contextlib.suppress(RuntimeError, subprocess.TimeoutExpired):
            self._run(str(self.bin / "pg_ctl"), "-D", str(self.data), "-m", "immediate", "-w", "stop")
        shutil.rmtree(self.root, ignore_errors=True)

    def url(self, schema: str | None = None) -> str:
        url = f"postgresql+psycopg://{PG_USER}@/postgres?host={self.root}"
        return url if schema is None else f"{url}&options=-csearch_path%3D{schema}"

    def new_database(self) -> str:
        """The URL of a fresh, empty schema (as good as a new database, and much faster to make)."""
        import sqlalchemy as sa

        name = f"record_{os.getpid()}_{next(self._names)}"
        engine = sa.create_engine(self.url(), isolation_level="AUTOCOMMIT")
        try:
            with engine.connect() as conn:
                conn.exec_driver_sql(f'CREATE SCHEMA "{name}"')
        finally:
            engine.dispose()
        return self.url(name)


@pytest.fixture(scope="session")
def postgres() -> Iterator[PostgresServer]:
    bin_dir = _pg_bin()
    needs_system("PostgreSQL server (initdb, pg_ctl)", bin_dir is not None, PG_HINT)
    assert bin_dir is not None
    if os.geteuid() == 0:
        try:
            pwd.getpwnam("postgres")
        except KeyError:
            needs_system("the postgres user (to run the server as non-root)", False, PG_HINT)
    server = PostgresServer(bin_dir)
    try:
        server.start()
        yield server
    finally:
        server.stop()


NewUrl = Callable[[], "str | None"]


@pytest.fixture(params=["sqlite", "postgresql"])
def new_url(request: pytest.FixtureRequest) -> NewUrl:
    """Makes record URLs of this test's backend: None (SQLite in the data directory) or a fresh
    PostgreSQL database each call."""
    if request.param == "sqlite":
        return lambda: None
    server: PostgresServer = request.getfixturevalue("postgres")
    return server.new_database


@pytest.fixture
def record_url(new_url: NewUrl) -> str | None:
    return new_url()


class StepClock:
    """An aware UTC clock that advances one millisecond per reading (ordering without sleeping)."""

    def __init__(self) -> None:
        self.now = datetime(2026, 11, 27, 12, 0, 0, tzinfo=UTC)

    def __call__(self) -> datetime:
        self.now += timedelta(milliseconds=1)
        return self.now


@pytest.fixture
def record(tmp_path: Path, record_url: str | None) -> Iterator[Record]:
    with Record(tmp_path / "data", record_url, clock=StepClock()) as rec:
        yield rec
