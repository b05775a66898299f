"""Helpers of the import tests (issue 18): an exported session to craft, and a snapshot of everything an
import could touch (the data directory's files, a victim folder outside it, the record's rows)."""

from __future__ import annotations

import hashlib
import io
import json
import os
import stat
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sqlalchemy as sa

from station.record import Record
from station.record._schema import metadata
from tests.record.test_export import _fill

SQLITE_OWN = {"record.sqlite", "record.sqlite-wal", "record.sqlite-shm"}
"""SQLite's own files: their bytes change with reads and checkpoints; the rows are compared instead."""


def tree(root: Path) -> dict[str, str]:
    """Every entry under ``root`` (links not followed): files by sha256, links by target, directories."""
    out: dict[str, str] = {}
    if not root.exists():
        return out
    for dirpath, dirnames, filenames in os.walk(root):
        for name in sorted(dirnames + filenames):
            p = Path(dirpath) / name
            rel = str(p.relative_to(root))
            if rel in SQLITE_OWN:
                continue
            st = p.lstat()
            if stat.S_ISLNK(st.st_mode):
                out[rel] = "link -> " + os.readlink(p)
            elif stat.S_ISDIR(st.st_mode):
                out[rel] = "dir"
            else:
                out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def rows(record: Record) -> dict[str, list[tuple[Any, ...]]]:
    """Every row of every table of the record, in key order."""
    out = {}
    with record.engine.connect() as conn:
        for table in metadata.sorted_tables:
            query = sa.select(table).order_by(*table.primary_key.columns)
            out[table.name] = [tuple(r) for r in conn.execute(query)]
    return out


@dataclass
class Scene:
    """A target record holding a ``victim`` session (with images), a ``victim folder`` outside its data
    directory, and an exported session ``sid`` (``folder``) to craft and import."""

    target: Record
    victim: str
    outside: Path
    source: Record
    sid: str
    folder: Path

    def snapshot(self) -> tuple[dict[str, str], dict[str, str], dict[str, list[tuple[Any, ...]]]]:
        return tree(self.target.data_dir), tree(self.outside), rows(self.target)

    def doc(self) -> dict[str, Any]:
        doc: dict[str, Any] = json.loads((self.folder / "session.json").read_text())
        return doc

    def write_doc(self, doc: dict[str, Any]) -> None:
        (self.folder / "session.json").write_text(json.dumps(doc, indent=1))

    def image(self, i: int) -> Path:
        return self.folder / self.doc()["captures"][i]["path"]


def make_scene(tmp_path: Path, source_url: str | None, target_url: str | None) -> Scene:
    from tests.record.conftest import StepClock

    target = Record(tmp_path / "d1" / "d2" / "data", target_url, clock=StepClock())
    victim = _fill(target)
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "notes.txt").write_text("the operator's notes: must survive any import\n")
    (outside / "victim.png").write_bytes((target.data_dir / target.captures(victim)[0].path).read_bytes())
    source = Record(tmp_path / "src", source_url, clock=StepClock())
    sid = _fill(source)
    folder = source.export_session(sid, tmp_path / "e1" / "e2" / "e3" / "e4")
    return Scene(target, victim, outside, source, sid, folder)


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def zipped(folder: Path, *, links: dict[str, str] | None = None) -> bytes:
    """The folder as ``export.zip`` lays it out (``<id>/...``); ``links``: extra symbolic-link entries
    (name -> target)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in sorted(folder.rglob("*")):
            if p.is_file() and not p.is_symlink():
                zf.write(p, Path(folder.name) / p.relative_to(folder))
        for name, target in (links or {}).items():
            info = zipfile.ZipInfo(f"{folder.name}/{name}")
            info.create_system = 3
            info.external_attr = (stat.S_IFLNK | 0o777) << 16
            zf.writestr(info, target)
    return buf.getvalue()
