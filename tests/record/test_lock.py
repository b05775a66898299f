"""One session at a time per station, across processes; a killed owner's lock is free."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
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
        assert holder == mine.holder
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
            assert lock_holder(tmp_path) == mine.holder
    finally:
        child.kill()
        child.wait(timeout=30)
        if child.stdout is not None:
            child.stdout.close()


def test_asking_who_holds_the_station_takes_no_lock_and_creates_nothing(tmp_path: Path) -> None:
    """``lock_holder`` tests the lock (``F_OFD_GETLK``) without taking it: a start that comes meanwhile
    is never refused because of it, and a station never used has no lock file made for the asking."""
    from station.record import station_in_use

    assert lock_holder(tmp_path) is None
    assert list(tmp_path.iterdir()) == []
    with station_lock(tmp_path, "eeee00000005") as held:
        assert lock_holder(tmp_path) == held.holder
        assert station_in_use(tmp_path)
    assert not station_in_use(tmp_path)


def test_the_station_is_released_before_the_final_word_and_the_next_holder_waits_for_it(
    tmp_path: Path,
) -> None:
    """A session frees the station (byte 0) as soon as its outcome is known and keeps the record's last
    word (byte 1) while it records it: the next session gets the station at once, and enters its block
    (where it reconciles the record) only once the previous one has left its own."""
    from station.record import station_in_use

    order: list[str] = []
    entered = threading.Event()
    with station_lock(tmp_path, "ffff00000006") as first:
        first.release()
        assert lock_holder(tmp_path) is None  # free for the next start
        assert station_in_use(tmp_path)  # but a process is still recording its final state

        def next_session() -> None:
            with station_lock(tmp_path, "ffff00000007"):
                order.append("second entered")
                entered.set()

        thread = threading.Thread(target=next_session)
        thread.start()
        while (lock_holder(tmp_path) or {}).get("session_id") != "ffff00000007":  # it holds byte 0 ...
            time.sleep(0.001)
        assert not entered.is_set()  # ... and waits for byte 1
        order.append("first left")
    thread.join(30)
    assert order == ["first left", "second entered"]
    assert lock_holder(tmp_path) is None
