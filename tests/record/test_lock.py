"""One session at a time per station, across processes; a killed owner's lock is free."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from station.record import SessionLockError, lock_holder, station_lock

HOLDER = """
import sys, time
from pathlib import Path
from station.record import station_lock
with station_lock(Path(sys.argv[1]), sys.argv[2]):
    print("locked", flush=True)
    time.sleep(120)
"""


def test_second_holder_is_refused_with_the_holders_name(tmp_path: Path) -> None:
    assert lock_holder(tmp_path) is None
    with station_lock(tmp_path, "aaaa00000001") as mine:
        holder = lock_holder(tmp_path)
        assert holder == mine
        assert holder["pid"] == os.getpid()
        assert holder["host"] == socket.gethostname()
        assert holder["session_id"] == "aaaa00000001"
        with (
            pytest.raises(SessionLockError, match=rf"session 'aaaa00000001' runs in process {os.getpid()}"),
            station_lock(tmp_path, "bbbb00000002"),
        ):
            pytest.fail("a second session got the station")
    assert lock_holder(tmp_path) is None
    with station_lock(tmp_path, "bbbb00000002"):
        assert lock_holder(tmp_path)["session_id"] == "bbbb00000002"  # type: ignore[index]


def test_lock_held_by_another_process_frees_when_it_is_killed(tmp_path: Path) -> None:
    child = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(tmp_path), "cccc00000003"],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == "locked"
        holder = lock_holder(tmp_path)
        assert holder is not None
        assert (holder["pid"], holder["session_id"]) == (child.pid, "cccc00000003")
        with (
            pytest.raises(SessionLockError, match=rf"process {child.pid} on host") as err,
            station_lock(tmp_path, "dddd00000004"),
        ):
            pytest.fail("took the station from a live session")
        assert err.value.holder["session_id"] == "cccc00000003"
        child.send_signal(signal.SIGKILL)
        assert child.wait(timeout=30) == -signal.SIGKILL
        assert lock_holder(tmp_path) is None
        with station_lock(tmp_path, "dddd00000004") as mine:
            assert lock_holder(tmp_path) == mine
    finally:
        child.kill()
        child.wait(timeout=30)
        if child.stdout is not None:
            child.stdout.close()
