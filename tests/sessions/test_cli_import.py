"""``station import DIR|ZIP`` (issue 18, item 1): the record's one import path from the command line; a
refusal is one line naming the field (exit 1), a path that does not exist is a usage error (exit 2),
and nothing is written either way."""

from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path

import pytest

from station.cli import main
from station.record import Record
from tests.record.importing import tree


def _export(recorded: tuple[Path, str], tmp_path: Path) -> Path:
    with Record(recorded[0], read_only=True) as rec:
        return rec.export_session(recorded[1], tmp_path / "out")


def test_an_export_folder_or_its_zip_imports(
    recorded: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _export(recorded, tmp_path)
    archive = tmp_path / "export.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        for p in sorted(folder.rglob("*")):
            zf.write(p, Path(folder.name) / p.relative_to(folder))
    assert main(["import", str(folder), "--data", str(tmp_path / "a")]) == 0
    assert main(["import", str(archive), "--data", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out.split()
    assert out == [recorded[1], recorded[1]]


def test_a_refused_import_is_one_line_exit_1_and_writes_nothing(
    recorded: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _export(recorded, tmp_path)
    doc = json.loads((folder / "session.json").read_text())
    doc["captures"][0]["path"] = "../../escape.png"
    (folder / "session.json").write_text(json.dumps(doc))
    data = tmp_path / "data"
    shutil.copytree(recorded[0], data)
    before = tree(data)
    assert main(["import", str(folder), "--data", str(data)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("station import: refused: session.json: captures[0].path: '../../escape.png'")
    assert err.count("\n") == 1
    assert tree(data) == before
    assert main(["import", str(tmp_path / "nothing-here"), "--data", str(data)]) == 2
    assert "no such folder or zip file" in capsys.readouterr().err
    assert tree(data) == before
