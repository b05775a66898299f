"""Issue 18, item 5 (table row 10): ``station sessions``, ``report`` and ``export`` only read the record.
Nothing is created or changed in the data directory (no lock file made to list), and they work on a
full disk and in a read-only data directory (real ones: a tmpfs filled to the last byte and a
read-only bind mount, in a mount namespace of their own)."""

from __future__ import annotations

import json
import shlex
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from station.record import Record
from tests.record.importing import tree

RUNNER = """
import contextlib, io, json, sys
from station.cli import main
done = []
for argv in json.loads(sys.argv[1]):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
    done.append({"code": code, "out": out.getvalue(), "err": err.getvalue()})
print(json.dumps(done))
"""


def stations(*commands: list[str], setup: str | None = None) -> list[dict[str, Any]]:
    """Run ``station`` commands, in order, in one process (the CLI's entry point, ``main``); with
    ``setup`` (shell), after it in a private mount namespace (its mounts vanish with it)."""
    argv = [sys.executable, "-c", RUNNER, json.dumps(list(commands))]
    if setup is not None:
        quoted = " ".join(shlex.quote(a) for a in argv)
        argv = ["unshare", "-m", "sh", "-c", f"set -e; {setup}; exec {quoted}"]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    results: list[dict[str, Any]] = json.loads(done.stdout.strip().splitlines()[-1])
    return results


def _copy(recorded: tuple[Path, str], where: Path) -> Path:
    data = where / "data"
    shutil.copytree(recorded[0], data)
    (data / "station.lock").unlink(missing_ok=True)  # as a station that never ran here would have
    return data


def test_reading_commands_change_nothing_in_the_data_directory(
    recorded: tuple[Path, str], tmp_path: Path
) -> None:
    data, sid = _copy(recorded, tmp_path), recorded[1]
    before = tree(data), sorted(p.name for p in data.iterdir())
    listed, table, exported, report = stations(
        ["sessions", "--json", "--data", str(data)],
        ["sessions", "--data", str(data)],
        ["export", sid, str(tmp_path / "out"), "--data", str(data)],
        ["report", sid, "--data", str(data), "--out", str(tmp_path / "report")],
    )
    assert listed["code"] == 0, listed["err"]
    assert [s["id"] for s in json.loads(listed["out"])] == [sid]
    assert table["code"] == 0, table["err"]
    assert exported["code"] == 0, exported["err"]
    assert report["code"] == 0, report["err"]
    assert (tmp_path / "report" / "report.html").is_file()
    assert (tree(data), sorted(p.name for p in data.iterdir())) == before  # no station.lock, no -wal
    with Record(data) as rec:
        assert rec.get_session(sid).state == "succeeded"


def test_sessions_on_a_data_directory_that_does_not_exist_lists_none_and_creates_nothing(
    tmp_path: Path,
) -> None:
    none = tmp_path / "none"
    listed, exported = stations(
        ["sessions", "--json", "--data", str(none)],
        ["export", "abcd", str(tmp_path / "out"), "--data", str(none)],
    )
    assert listed["code"] == 0, listed["err"]
    assert json.loads(listed["out"]) == []
    assert "no record in" in listed["err"]
    assert exported["code"] == 1
    assert "no record in" in exported["err"]
    assert not none.exists()


def _namespace_available() -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(
        ["unshare", "-m", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"],
        capture_output=True,
        timeout=30,
        check=False,
    )
    return probe.returncode == 0


needs_mounts = pytest.mark.skipif(
    not _namespace_available(), reason="needs a mount namespace (root with CAP_SYS_ADMIN: unshare -m)"
)


def _fill(mount: Path) -> str:
    """Shell that fills ``mount`` to its last byte (dd stops with ENOSPC)."""
    fill = f"(dd if=/dev/zero of={mount}/filler bs=4k 2>/dev/null || true)"
    return f"{fill}; (dd if=/dev/zero of={mount}/crumbs bs=1 2>/dev/null || true)"


@needs_mounts
def test_sessions_export_and_report_work_on_a_full_disk(recorded: tuple[Path, str], tmp_path: Path) -> None:
    """Table row 10: ``station sessions`` crashed with ENOSPC (it made the lock file to list)."""
    src, sid = _copy(recorded, tmp_path / "src"), recorded[1]
    mount = tmp_path / "full"
    mount.mkdir()
    out = tmp_path / "out"
    listed, exported, report, elsewhere = stations(
        ["sessions", "--json", "--data", str(mount)],
        ["export", sid, str(out), "--data", str(mount)],
        ["report", sid, "--data", str(mount)],
        ["report", sid, "--data", str(mount), "--out", str(tmp_path / "r")],
        setup=f"mount -t tmpfs -o size=4m tmpfs {mount}; cp -a {src}/. {mount}/; {_fill(mount)}",
    )
    assert listed["code"] == 0, listed["err"]
    assert [(s["id"], s["state"]) for s in json.loads(listed["out"])] == [(sid, "succeeded")]
    assert exported["code"] == 0, exported["err"]
    assert (out / sid / "session.json").is_file()
    assert report["code"] == 1  # its default folder is on the full disk: the error says what to do
    assert "give --out DIR" in report["err"]
    assert "Traceback" not in report["err"]
    assert elsewhere["code"] == 0, elsewhere["err"]


@needs_mounts
def test_sessions_and_export_work_in_a_read_only_data_directory(
    recorded: tuple[Path, str], tmp_path: Path
) -> None:
    src, sid = _copy(recorded, tmp_path / "src"), recorded[1]
    listed, exported, run = stations(
        ["sessions", "--json", "--data", str(src)],
        ["export", sid, str(tmp_path / "out"), "--data", str(src)],
        ["run", "reanalyse", "--param", f"session={sid}", "--data", str(src), "--json"],
        setup=f"mount --bind {src} {src}; mount -o remount,bind,ro {src}",
    )
    assert listed["code"] == 0, listed["err"]
    assert [s["id"] for s in json.loads(listed["out"])] == [sid]
    assert exported["code"] == 0, exported["err"]
    assert run["code"] == 1  # a command that writes says why, in one line, and --json its outcome
    assert "Traceback" not in run["err"]
    assert json.loads(run["out"].strip().splitlines()[-1])["state"] == "failed"
