"""Issue 18 (the Must, table rows 1, 2, 4 and 6): an export folder crafted to reach outside itself or the
session's own images is refused, and the import creates, changes and removes nothing outside its
staging directory: the data directory's files, a victim folder outside it and the record's rows are
the same before and after (SQLite and PostgreSQL)."""

from __future__ import annotations

import io
import os
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa

from station.record import Record, RecordError
from tests.record.conftest import NewUrl
from tests.record.importing import Scene, make_scene, sha256, zipped


def _scene(tmp_path: Path, url: str | None) -> Iterator[Scene]:
    s = make_scene(tmp_path, None, url)
    try:
        yield s
    finally:
        s.source.close()
        s.target.close()


@pytest.fixture
def scene(tmp_path: Path, new_url: NewUrl) -> Iterator[Scene]:
    """On SQLite and on PostgreSQL."""
    yield from _scene(tmp_path, new_url())


@pytest.fixture
def sqlite_scene(tmp_path: Path) -> Iterator[Scene]:
    """On SQLite only: the archive's checks come before the database."""
    yield from _scene(tmp_path, None)


def relative_escape(s: Scene) -> str:
    """Table row 1: a capture path ``../../../outside/pwned.txt``, whose sha256 is that of a file the
    folder reaches at the same relative place."""
    path = "../../../outside/pwned.txt"
    payload = s.image(0).read_bytes()
    planted = s.folder / path
    planted.parent.mkdir(parents=True, exist_ok=True)
    planted.write_bytes(payload)
    assert planted.resolve() != (s.target.data_dir / path).resolve()  # the write would land in ``outside``
    doc = s.doc()
    doc["captures"][0].update(path=path, sha256=sha256(payload))
    s.write_doc(doc)
    return "captures[0].path"


def absolute_and_a_later_failure(s: Scene) -> str:
    """Table row 2: a capture names an existing file by its absolute path, with its real sha256; a later
    capture's sha256 is wrong (the old import then deleted what it had 'written', the victim file)."""
    victim = s.outside / "victim.png"
    doc = s.doc()
    doc["captures"][0].update(path=str(victim), sha256=sha256(victim.read_bytes()))
    doc["captures"][-1]["sha256"] = "0" * 64
    s.write_doc(doc)
    return "captures[0].path"


def another_sessions_image(s: Scene) -> str:
    """Table row 2: a capture names another session's image (``images/<victim>/...``), with bytes of its
    own and their sha256 (the old import overwrote the victim's image with them)."""
    theirs = s.target.captures(s.victim)[0].path
    garbage = s.image(1).read_bytes()
    (s.folder / theirs).parent.mkdir(parents=True, exist_ok=True)
    (s.folder / theirs).write_bytes(garbage)
    doc = s.doc()
    doc["captures"][0].update(path=theirs, sha256=sha256(garbage))
    s.write_doc(doc)
    return "captures[0].path"


def symlinked_image(s: Scene) -> str:
    """Table row 6: an image of the folder is a symbolic link to a file outside it (same bytes)."""
    image = s.image(2)
    secret = s.outside.parent / "secret" / "real.png"
    secret.parent.mkdir()
    secret.write_bytes(image.read_bytes())
    image.unlink()
    image.symlink_to(secret)
    return "captures[2].path"


def symlinked_folder(s: Scene) -> str:
    """The session's image folder inside the export is a symbolic link to a folder outside it."""
    images = s.folder / "images" / s.sid
    moved = s.outside.parent / "elsewhere"
    images.rename(moved)
    images.symlink_to(moved, target_is_directory=True)
    return "captures[0].path"


def a_failing_later_capture(s: Scene) -> str:
    """Every capture but the last is fine and staged; the last one's bytes do not match its sha256."""
    s.image(-1).write_bytes(s.image(0).read_bytes())
    return "captures[5].sha256"


def escaping_session_id(s: Scene) -> str:
    """Table row 4: the session id ``dddd0000dddd/../../../../outside/report_escape`` everywhere the id
    appears (its capture paths too, their images planted where those paths lead from the folder); the
    old import committed it, and the report of ``dddd0000`` was then written outside."""
    crafted = "dddd0000dddd/../../../../outside/report_escape"
    (s.folder / "images" / "dddd0000dddd").mkdir()
    for c in s.doc()["captures"]:
        planted = (s.folder / c["path"].replace(s.sid, crafted)).resolve()
        planted.parent.mkdir(parents=True, exist_ok=True)
        planted.write_bytes((s.folder / c["path"]).read_bytes())
    text = (s.folder / "session.json").read_text()
    (s.folder / "session.json").write_text(text.replace(s.sid, crafted))
    return "session.id"


CRAFTED: list[Callable[[Scene], str]] = [
    relative_escape,
    absolute_and_a_later_failure,
    another_sessions_image,
    symlinked_image,
    symlinked_folder,
    a_failing_later_capture,
    escaping_session_id,
]


@pytest.mark.parametrize("craft", CRAFTED, ids=[c.__name__ for c in CRAFTED])
def test_a_crafted_folder_is_refused_and_nothing_outside_the_staging_directory_changes(
    scene: Scene, craft: Callable[[Scene], str]
) -> None:
    field = craft(scene)
    before = scene.snapshot()
    try:
        scene.target.import_session(scene.folder)
    except RecordError as exc:
        refused: RecordError | None = exc
    else:
        refused = None
    after = scene.snapshot()
    assert after[1] == before[1], "the victim folder outside the data directory changed"
    assert after[0] == before[0], "the data directory's files changed"
    assert after[2] == before[2], "the record's rows changed"
    assert refused is not None, "the crafted folder was imported"
    message = str(refused)
    assert field in message, message
    assert "\n" not in message
    assert [s.id for s in scene.target.list_sessions()] == [scene.victim]
    scene.target.export_session(scene.victim, scene.outside.parent / "victim-export")  # still whole


@pytest.mark.parametrize("craft", CRAFTED, ids=[c.__name__ for c in CRAFTED])
def test_the_same_crafts_zipped_are_refused_alike(sqlite_scene: Scene, craft: Callable[[Scene], str]) -> None:
    scene = sqlite_scene
    craft(scene)
    links = {}
    if craft is symlinked_image:  # zipped, the link is an entry of its own
        links = {scene.doc()["captures"][2]["path"]: str(scene.outside.parent / "secret" / "real.png")}
    data = zipped(scene.folder, links=links)
    before = scene.snapshot()
    with pytest.raises(RecordError) as refused:
        scene.target.import_archive(io.BytesIO(data))
    assert "\n" not in str(refused.value)
    assert scene.snapshot() == before


def test_an_unchanged_export_still_imports_and_the_staging_directory_is_gone(scene: Scene) -> None:
    imported = scene.target.import_session(scene.folder)
    assert imported == scene.source.get_session(scene.sid)
    assert not [p for p in os.listdir(scene.target.data_dir) if p.startswith(".import-")]
    for a, b in zip(scene.source.captures(scene.sid), scene.target.captures(scene.sid), strict=True):
        assert (scene.target.data_dir / b.path).read_bytes() == (scene.source.data_dir / a.path).read_bytes()


def test_a_failing_commit_takes_the_moved_images_back(scene: Scene) -> None:
    """The images are renamed into place inside the transaction; when the commit then fails (a full disk,
    a lost server: injected at the commit, the import's only one), they go back to the staging directory
    and are removed with it."""
    failing = [True]

    @sa.event.listens_for(scene.target.engine, "commit")
    def _commit(conn: sa.Connection) -> None:
        if failing[0]:
            assert (scene.target.data_dir / "images" / scene.sid).is_dir()  # moved before the commit
            raise sa.exc.OperationalError("COMMIT", {}, Exception("disk I/O error (injected)"))

    before = scene.snapshot()
    try:
        with pytest.raises(RecordError, match="disk I/O error"):
            scene.target.import_session(scene.folder)
    finally:
        failing[0] = False
    assert scene.snapshot() == before
    assert scene.target.import_session(scene.folder).id == scene.sid  # nothing was left in its way


def test_a_folder_named_like_the_session_in_images_is_never_replaced(scene: Scene) -> None:
    """A stray ``images/<id>`` (the record has no such session) is not the import's: refused, untouched."""
    stray = scene.target.data_dir / "images" / scene.sid
    stray.mkdir()
    (stray / "keep.txt").write_text("not the import's")
    before = scene.snapshot()
    with pytest.raises(RecordError, match="move that folder out of the data directory"):
        scene.target.import_session(scene.folder)
    assert scene.snapshot() == before


def test_records_of_the_old_imports_do_not_read_outside(tmp_path: Path) -> None:
    """A capture row whose path an earlier import took unchecked is refused when its image is read."""
    from station.record._schema import captures

    with Record(tmp_path / "data") as rec:
        from tests.record.test_export import _fill

        sid = _fill(rec)
        cap = rec.captures(sid)[0]
        with rec.engine.begin() as conn:
            conn.execute(sa.update(captures).where(captures.c.id == cap.id).values(path="../../etc/passwd"))
        with pytest.raises(RecordError, match="the record was altered"):
            rec.load_image(rec.capture(cap.id))
        with pytest.raises(RecordError, match="the record was altered"):
            rec.export_session(sid, tmp_path / "out")


def test_a_session_id_an_old_import_took_unchecked_is_refused_when_read(tmp_path: Path) -> None:
    """Table row 4's second half: the report of ``dddd0000`` was written where its id led (SQLite keeps
    any length in the id column): such a row is refused when it is looked up, before any path is made."""
    from station.record._schema import sessions

    with Record(tmp_path / "data") as rec:
        row = rec.create_session("validation", params={}, config={}, identities={}, software={})
        values = {**row.__dict__, "id": "dddd0000dddd/../../../../outside/report_escape"}
        with rec.engine.begin() as conn:
            conn.execute(sa.insert(sessions).values(**values))
        with pytest.raises(RecordError, match="is not 12 hex digits"):
            rec.get_session("dddd0000")
