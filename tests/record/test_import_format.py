"""Issue 18 (table rows 5 and 6): an import checks every key, type and unit of ``session.json``, every
image through the front door, and every entry of a zip, and refuses with one line naming the field;
nothing is written (the record and the data directory stay as they were)."""

from __future__ import annotations

import io
import json
import struct
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from station.record import RecordError
from tests.record.importing import Scene, make_scene, sha256, zipped


@pytest.fixture
def scene(tmp_path: Path) -> Iterator[Scene]:
    s = make_scene(tmp_path, None, None)
    try:
        yield s
    finally:
        s.source.close()
        s.target.close()


def _refused(scene: Scene, field: str, do: Callable[[], object] | None = None) -> str:
    before = scene.snapshot()
    with pytest.raises(RecordError) as refused:
        (do or (lambda: scene.target.import_session(scene.folder)))()
    message = str(refused.value)
    assert field in message, message
    assert "\n" not in message
    assert scene.snapshot() == before
    return message


def _edit(scene: Scene, change: Callable[[dict[str, Any]], None]) -> None:
    doc = scene.doc()
    change(doc)
    scene.write_doc(doc)


DOCUMENTS: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    ("missing steps", lambda d: d.pop("steps"), "steps: is missing"),
    ("an extra session key", lambda d: d["session"].update(owner="x"), "session.owner: is not a key"),
    ("a bad timestamp", lambda d: d["steps"][0].update(started_at="yesterday"), "steps[0].started_at"),
    ("a naive time", lambda d: d["session"].update(created_at="2026-01-01T00:00:00"), "session.created_at"),
    ("an unknown state", lambda d: d["session"].update(state="bogus"), "session.state"),
    ("a width as text", lambda d: d["captures"][0].update(width="56"), "captures[0].width"),
    ("a negative frame", lambda d: d["captures"][0].update(frame_index=-1), "captures[0].frame_index"),
    ("a repeated frame", lambda d: d["captures"][1].update(frame_index=0), "captures[1]"),
    ("a repeated event seq", lambda d: d["events"][1].update(seq=1), "events[1].seq"),
    ("a bad sha256", lambda d: d["captures"][0].update(sha256="XYZ"), "captures[0].sha256"),
    ("no own capture", lambda d: d["measurements"][0]["capture"].update(step_index=9), "measurements[0]"),
    ("a bad parent id", lambda d: d["session"].update(parent_id="../x"), "session.parent_id"),
    ("a newer format", lambda d: d.update(format_version=2), "format_version"),
    ("another format", lambda d: d.update(format="other"), "format"),
    ("results not an object", lambda d: d["session"].update(results=[1, 2]), "session.results"),
]  # fmt: skip


@pytest.mark.parametrize(("name", "change", "field"), DOCUMENTS, ids=[d[0] for d in DOCUMENTS])
def test_a_document_out_of_the_format_is_refused_naming_the_field(
    scene: Scene, name: str, change: Callable[[dict[str, Any]], None], field: str
) -> None:
    _edit(scene, change)
    _refused(scene, field)


@pytest.mark.parametrize(
    ("where", "bad", "field"),
    [
        ('"mean_um": 0.05', '"mean_um": NaN', "session.results.mean_um"),
        ('"timestamp_s": 0.0', '"timestamp_s": Infinity', "captures[0].timestamp_s"),
        ('"center_px": [20.0, 28.0]', '"center_px": [NaN, 28.0]', "measurements[0].result.center_px[0]"),
    ],
)
def test_nan_and_infinity_are_refused_where_they_are(scene: Scene, where: str, bad: str, field: str) -> None:
    """Table row 6: a NaN in an imported session's results made its export, figures and report fail."""
    text = (scene.folder / "session.json").read_text()
    assert where in text
    (scene.folder / "session.json").write_text(text.replace(where, bad, 1))
    _refused(scene, field)


def test_text_that_is_not_json_is_refused(scene: Scene) -> None:
    (scene.folder / "session.json").write_text('{"format": "station-session", ')
    _refused(scene, "session.json: is not valid JSON")


def test_a_corrupt_png_with_its_sha256_is_refused_by_the_front_door(scene: Scene) -> None:
    """Table row 6: a corrupt PNG whose sha256 matches (the export was made so) was accepted."""
    png = bytearray(scene.image(1).read_bytes())
    png[60:90] = b"\x00" * 30  # inside the image data: the zlib stream breaks
    scene.image(1).write_bytes(bytes(png))
    _edit(scene, lambda d: d["captures"][1].update(sha256=sha256(bytes(png))))
    message = _refused(scene, "captures[1].path")
    assert "corrupt" in message or "unreadable" in message or "truncated" in message, message


def test_an_image_unlike_its_row_is_refused(scene: Scene) -> None:
    _edit(scene, lambda d: d["captures"][0].update(width=57))
    _refused(scene, "captures[0].path")


def test_a_colour_image_is_refused(scene: Scene) -> None:
    ok, buf = cv2.imencode(".png", np.zeros((40, 56, 3), np.uint8))
    assert ok
    scene.image(0).write_bytes(buf.tobytes())
    _edit(scene, lambda d: d["captures"][0].update(sha256=sha256(buf.tobytes())))
    _refused(scene, "captures[0].path")


def test_session_json_as_a_link_is_refused(scene: Scene) -> None:
    real = scene.outside.parent / "elsewhere.json"
    (scene.folder / "session.json").rename(real)
    (scene.folder / "session.json").symlink_to(real)
    _refused(scene, "session.json")


def test_a_measurement_of_a_session_not_in_the_record_names_it(scene: Scene) -> None:
    _edit(scene, lambda d: d["measurements"][0]["capture"].update(session_id="abcdef012345"))
    message = _refused(scene, "measurements[0].capture")
    assert "import session abcdef012345 first" in message


# ------------------------------------------------------------------------------------------- zip


def _archive(scene: Scene, data: bytes, limits: Any = None) -> Callable[[], object]:
    return lambda: scene.target.import_archive(io.BytesIO(data), limits=limits)


def _limits(**caps: int) -> Any:
    from station.record import ArchiveLimits

    return ArchiveLimits(**caps)


def test_a_zip_of_an_unchanged_export_imports(scene: Scene) -> None:
    row = scene.target.import_archive(io.BytesIO(zipped(scene.folder)))
    assert row == scene.source.get_session(scene.sid)


def _entries(files: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return buf.getvalue()


@pytest.mark.parametrize(
    ("name", "field"),
    [
        ("../evil.txt", "'../evil.txt'"),
        ("/etc/evil.txt", "'/etc/evil.txt'"),
        ("a/../../evil.txt", "'a/../../evil.txt'"),
        ("C:/evil.txt", "'C:/evil.txt'"),
        ("a\\..\\evil.txt", "'a\\\\..\\\\evil.txt'"),
    ],
)
def test_zip_entry_names_outside_the_archive_are_refused(scene: Scene, name: str, field: str) -> None:
    data = zipped(scene.folder)
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        files = {i.filename: zf.read(i) for i in zf.infolist()}
    files[name] = b"x"
    _refused(scene, f"archive entry {field}", _archive(scene, _entries(files)))


def test_a_zip_whose_declared_size_lies_is_refused(scene: Scene) -> None:
    """Table row 5: an archive whose central directory declares other sizes than its data (the old
    route answered 500 BadZipFile)."""
    data = bytearray(zipped(scene.folder))
    with zipfile.ZipFile(io.BytesIO(bytes(data))) as zf:
        info = next(i for i in zf.infolist() if i.filename.endswith("00000-00.png"))
    at = data.find(b"PK\x01\x02")  # the central directory's headers: find this entry's
    while at >= 0:
        name_len = struct.unpack("<H", data[at + 28 : at + 30])[0]
        if data[at + 46 : at + 46 + name_len].decode() == info.filename:
            break
        at = data.find(b"PK\x01\x02", at + 4)
    assert at >= 0
    data[at + 24 : at + 28] = struct.pack("<L", info.file_size - 100)  # its uncompressed size
    _refused(scene, "00000-00.png", _archive(scene, bytes(data)))


def test_caps_on_entries_and_declared_size(scene: Scene) -> None:
    data = zipped(scene.folder)
    _refused(scene, "entries, over the 3 limit", _archive(scene, data, _limits(max_entries=3)))
    _refused(scene, "of content, over the limit", _archive(scene, data, _limits(max_total_bytes=1000)))
    _refused(scene, "central directory", _archive(scene, data, _limits(max_directory_bytes=100)))


def test_not_a_zip_two_sessions_and_repeated_entries_are_refused(scene: Scene) -> None:
    _refused(scene, "archive: is not a zip archive", _archive(scene, b"PK not a zip"))
    two = _entries({"a/session.json": b"{}", "b/session.json": b"{}"})
    _refused(scene, "found 2", _archive(scene, two))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("x/session.json", b"{}")
        with pytest.warns(UserWarning, match="Duplicate name"):
            zf.writestr("x/session.json", b"{}")
    _refused(scene, "appears twice", _archive(scene, buf.getvalue()))


def test_a_zip64_archive_is_sized_from_its_zip64_end_record(scene: Scene) -> None:
    """Over 65,535 entries a zip's counts live in its zip64 end records: the cap reads them there."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for i in range(65_600):
            zf.writestr(f"x/f{i}", b"")
    message = _refused(
        scene, "entries, over the", _archive(scene, buf.getvalue(), _limits(max_entries=65_599))
    )
    assert "65600" in message


def test_a_json_bomb_of_nesting_is_refused(scene: Scene) -> None:
    doc = scene.doc()
    text = json.dumps(doc)
    deep = "[" * 100_000 + "]" * 100_000
    (scene.folder / "session.json").write_text(
        text.replace('"data": {"index": 0}', f'"data": {{"x": {deep}}}', 1)
    )
    _refused(scene, "session.json")


def test_refusals_leave_no_staging_directory(scene: Scene) -> None:
    _edit(scene, lambda d: d["captures"][-1].update(sha256="0" * 64))
    _refused(scene, "captures[5].sha256")
    assert not [p for p in scene.target.data_dir.iterdir() if p.name.startswith(".import-")]
