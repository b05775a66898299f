"""Issue 18 through the service: ``POST /api/v1/sessions/import`` is the record's one import path (crafted
archives 422 naming the field, nothing written: table rows 1, 2 and 5), a client that sees
``succeeded`` starts the next session at once while others read (row 11), and ``GET /station`` shows
the record's URL without its passwords (row 12)."""

from __future__ import annotations

import hashlib
import io
import json
import threading
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from api import Access, ServiceSettings, StationService
from station.kinds import get_plan
from station.plans import parse_params
from station.record import Record
from station.runner import SessionRunner, SessionState
from station.testing import FakeStation
from tests.api.conftest import FINAL, TOKEN, Served, ServeFactory, serve
from tests.record.conftest import PostgresServer, postgres  # noqa: F401 - the server fixture
from tests.record.importing import tree

ZIP = {"content-type": "application/zip"}
API_LOOPS = 50
"""Starts through the service (the 200-start loop is the runner's, tests/sessions/test_station_lock.py):
each costs a request, the worker's pipe and a re-analysis, 0.2-0.8 s on a loaded 2-core machine."""


@pytest.fixture(scope="module")
def export_zip(tmp_path_factory: pytest.TempPathFactory) -> tuple[bytes, str]:
    """A small validation (three positions, on the in-process fakes) as ``export.zip`` lays it out."""
    root = tmp_path_factory.mktemp("source")
    with Record(root / "data") as rec:
        plan = get_plan("validation")
        runner = SessionRunner(
            rec,
            plan,
            parse_params(plan, {"pattern_um": [[0, 0], [254, 0], [0, 254]]}),
            devices=FakeStation().devices(),
        )
        assert runner.run() is SessionState.SUCCEEDED, runner.error
        assert runner.session_id is not None
        folder = rec.export_session(runner.session_id, root / "out")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in sorted(folder.rglob("*")):
            if p.is_file():
                zf.write(p, Path(folder.name) / p.relative_to(folder))
    return buf.getvalue(), runner.session_id


@pytest.fixture
def offline(make_served: ServeFactory) -> Served:
    """The service without a station (offline plans only: no simulator to start)."""
    return make_served(sim=False)


def _files(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        return {i.filename: zf.read(i) for i in zf.infolist()}


def _zip(files: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return buf.getvalue()


def _crafted(
    export: tuple[bytes, str], victim: str, change: Callable[[dict[str, Any], dict[str, bytes], str], None]
) -> bytes:
    data, sid = export
    files = _files(data)
    doc = json.loads(files[f"{sid}/session.json"])
    change(doc, files, victim)
    files[f"{sid}/session.json"] = json.dumps(doc).encode()
    return _zip(files)


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def relative_escape(doc: dict[str, Any], files: dict[str, bytes], victim: str) -> None:
    """Row 1: a path that climbs out of the data directory and back into the archive's folder."""
    c = doc["captures"][0]
    c["path"] = f"../{doc['session']['id']}/{c['path']}"


def another_sessions_image(doc: dict[str, Any], files: dict[str, bytes], victim: str) -> None:
    """Row 2: the victim session's image, overwritten with other bytes (their sha256 given)."""
    sid = doc["session"]["id"]
    garbage = files[f"{sid}/{doc['captures'][1]['path']}"]
    files[f"{sid}/images/{victim}/00000-00.png"] = garbage
    doc["captures"][0].update(path=f"images/{victim}/00000-00.png", sha256=_sha(garbage))


def another_sessions_image_then_a_failure(doc: dict[str, Any], files: dict[str, bytes], victim: str) -> None:
    """Row 2: the victim's image with its own bytes, then a capture that fails (the old clean-up deleted
    the victim's image)."""
    another_sessions_image(doc, files, victim)
    sid = doc["session"]["id"]
    files[f"{sid}/images/{victim}/00000-00.png"] = VICTIM_IMAGE[victim]
    doc["captures"][0]["sha256"] = _sha(VICTIM_IMAGE[victim])
    doc["captures"][-1]["sha256"] = "0" * 64


def missing_steps(doc: dict[str, Any], files: dict[str, bytes], victim: str) -> None:
    """Row 5: the old route answered 500 KeyError."""
    del doc["steps"]


def extra_session_key(doc: dict[str, Any], files: dict[str, bytes], victim: str) -> None:
    """Row 5: the old route answered 500 CompileError."""
    doc["session"]["owner"] = "mallory"


def bad_timestamp(doc: dict[str, Any], files: dict[str, bytes], victim: str) -> None:
    """Row 5: the old route answered 500 ValueError."""
    doc["events"][0]["time"] = "the day before yesterday"


VICTIM_IMAGE: dict[str, bytes] = {}
CRAFTS = [
    (relative_escape, "captures[0].path"),
    (another_sessions_image, "captures[0].path"),
    (another_sessions_image_then_a_failure, "captures[0].path"),
    (missing_steps, "steps"),
    (extra_session_key, "session.owner"),
    (bad_timestamp, "events[0].time"),
]


@pytest.mark.parametrize(("craft", "field"), CRAFTS, ids=[c[0].__name__ for c in CRAFTS])
def test_a_crafted_archive_is_422_naming_the_field_and_nothing_is_written(
    offline: Served, export_zip: tuple[bytes, str], craft: Callable[..., None], field: str
) -> None:
    record = offline.service.record
    with offline.client() as c:  # a victim session, imported from another station
        victim_zip, victim = _victim(export_zip)
        assert c.post("/api/v1/sessions/import", content=victim_zip, headers=ZIP).status_code == 201
        VICTIM_IMAGE[victim] = (record.data_dir / "images" / victim / "00000-00.png").read_bytes()
        outside = record.data_dir.parent
        before = tree(outside), [s.id for s in record.list_sessions()]
        r = c.post("/api/v1/sessions/import", content=_crafted(export_zip, victim, craft), headers=ZIP)
        assert r.status_code == 422, r.text
        assert r.headers["content-type"] == "application/problem+json"
        body = r.json()
        assert body["code"] in ("import_refused", "bad_archive")
        assert field in body["detail"]
        assert "\n" not in body["detail"]
        assert (tree(outside), [s.id for s in record.list_sessions()]) == before
        assert c.get(f"/api/v1/sessions/{victim}/export.zip").status_code == 200  # still whole


def _victim(export: tuple[bytes, str]) -> tuple[bytes, str]:
    """The same export under another session id (a session of 'another station')."""
    data, sid = export
    victim = "0123456789ab"
    files = {}
    for name, content in _files(data).items():
        new = name.replace(sid, victim)
        files[new] = (
            content.replace(sid.encode(), victim.encode()) if name.endswith("session.json") else content
        )
    return _zip(files), victim


def test_a_zip_whose_declared_sizes_lie_is_422(offline: Served, export_zip: tuple[bytes, str]) -> None:
    """Row 5: the old route answered 500 BadZipFile."""
    data = bytearray(export_zip[0])
    at = data.find(b"PK\x01\x02")  # the first central directory entry: halve its declared size
    size = int.from_bytes(data[at + 24 : at + 28], "little")
    data[at + 24 : at + 28] = (size // 2).to_bytes(4, "little")
    with offline.client() as c:
        r = c.post("/api/v1/sessions/import", content=bytes(data), headers=ZIP)
    assert r.status_code == 422, r.text
    assert r.json()["code"] == "bad_archive"


class _Reader(threading.Thread):
    """Another client reading the station and the sessions without pause."""

    def __init__(self, served: Served) -> None:
        super().__init__(name="reader", daemon=True)
        self.served = served
        self.done = threading.Event()
        self.count = 0
        self.errors: list[str] = []

    def run(self) -> None:
        with self.served.client() as c:
            while not self.done.wait(0.005):  # a pause, or this thread starves the server's
                for path in ("/api/v1/station", "/api/v1/sessions"):
                    r = c.get(path)
                    if r.status_code != 200:
                        self.errors.append(f"{path}: {r.status_code} {r.text[:200]}")
                self.count += 1


def test_a_client_that_sees_succeeded_starts_the_next_session_at_once(
    offline: Served, export_zip: tuple[bytes, str]
) -> None:
    """Row 11: 50 times, a re-analysis is posted the moment the previous one is seen ``succeeded``,
    while another client reads the station and the sessions all along: never a 409."""
    reader = _Reader(offline)
    with offline.client() as c:
        assert c.post("/api/v1/sessions/import", content=export_zip[0], headers=ZIP).status_code == 201
        reader.start()
        refused: list[str] = []
        try:
            for _ in range(API_LOOPS):
                r = c.post(
                    "/api/v1/sessions", json={"kind": "reanalyse", "params": {"session": export_zip[1]}}
                )
                if r.status_code != 201:
                    refused.append(f"{r.status_code} {r.text[:300]}")
                    break
                sid = r.json()["id"]
                polling = threading.Event()
                while (state := c.get(f"/api/v1/sessions/{sid}").json()["state"]) not in FINAL:
                    polling.wait(0.002)  # the next post follows the first succeeded seen
                assert state == "succeeded", c.get(f"/api/v1/sessions/{sid}").text
        finally:
            reader.done.set()
            reader.join(30)
    assert refused == []
    assert reader.errors == []
    assert reader.count > 0


def test_the_station_shows_the_records_url_without_its_passwords(
    postgres: PostgresServer,  # noqa: F811 - the fixture
    tmp_path: Path,
) -> None:
    """Row 12: ``?password=`` (and a user-part password) of the record's URL were shown by ``GET
    /station``; the server trusts its socket, so the passwords here are never checked, only hidden."""
    url = postgres.new_database().replace(
        "postgresql+psycopg://station@", "postgresql+psycopg://station:s3cr3t-user@"
    )
    url += "&password=s3cr3t-query"
    served = serve(StationService(ServiceSettings(data=tmp_path / "data", database=url)), Access(TOKEN, True))
    try:
        with served.client() as c:
            doc = c.get("/api/v1/station").json()
            text = json.dumps(doc)
            assert "s3cr3t" not in text
            assert doc["record"].startswith("postgresql+psycopg://station:***@")
            assert "password=***" in doc["record"]
            assert "s3cr3t" not in repr(served.service.settings)
    finally:
        served.stop()
