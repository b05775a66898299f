"""``station serve`` that cannot start says why in one line (issue 18, rows 10 and 15): a short token
(exit 2), a port in use, an address that is not this machine's, a data directory it cannot use, a full
disk (exit 1). Each is refused before the station's worker starts, or as it starts."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

TOKEN = "start-test-token-0123456789"


def serve(*args: str, token: str | None = TOKEN, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("STATION_API_TOKEN", "STATION_ALLOWED_HOSTS")}
    if token is not None:
        env["STATION_API_TOKEN"] = token
    return subprocess.run(
        [sys.executable, "-m", "station.cli", "serve", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=timeout,
        check=False,
    )


def one_line(done: subprocess.CompletedProcess[str]) -> str:
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert done.stdout == ""
    assert lines[0].startswith("station serve: ")
    return lines[0]


def test_a_short_token_exits_2_saying_how_long_it_must_be(tmp_path: Path) -> None:
    """Row 15: it exited 2 and printed nothing."""
    done = serve("--port", "0", "--data", str(tmp_path / "data"), token="short-token")
    assert done.returncode == 2
    line = one_line(done)
    assert "the API token needs at least 16 characters" in line
    assert "short-token" not in line  # the token itself is never shown
    assert not (tmp_path / "data").exists()  # refused before anything was made


def test_a_short_configured_token_exits_2_too(tmp_path: Path) -> None:
    config = tmp_path / "station.toml"
    config.write_text('name = "t"\n[camera]\ndriver = "v4l2"\n[api]\ntoken = "0123456789"\n')
    done = serve("--config", str(config), "--port", "0", "--data", str(tmp_path / "data"), token=None)
    assert done.returncode == 2
    assert "the API token needs at least 16 characters (the configuration's [api] token has 10)" in one_line(
        done
    )


def test_a_port_in_use_is_one_line(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        done = serve("--port", str(port), "--data", str(tmp_path / "data"))
    assert done.returncode == 1
    assert f"cannot listen on 127.0.0.1:{port}: the port is in use" in one_line(done)


def test_an_address_of_another_machine_is_one_line(tmp_path: Path) -> None:
    done = serve("--host", "192.0.2.1", "--port", "0", "--data", str(tmp_path / "data"))  # TEST-NET-1
    assert done.returncode == 1
    assert "cannot listen on 192.0.2.1:0" in one_line(done)


def test_a_data_directory_that_is_a_file_is_one_line(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.write_text("not a directory")
    done = serve("--port", "0", "--data", str(data))
    assert done.returncode == 1
    assert "cannot start:" in one_line(done)
    assert data.read_text() == "not a directory"


def test_a_bad_allowed_host_is_a_usage_error(tmp_path: Path) -> None:
    done = serve("--allowed-host", "evil.example/../x", "--port", "0", "--data", str(tmp_path / "data"))
    assert done.returncode == 2
    assert "is not a host name" in done.stderr


def test_a_full_data_directory_is_one_line(tmp_path: Path) -> None:
    """Row 10's service half: station serve on a full disk exited 1 with nothing on stdout or stderr.
    A 256 KiB tmpfs, filled, in a mount namespace of its own (root, util-linux's unshare)."""
    unshare = shutil.which("unshare")
    if os.geteuid() != 0 or unshare is None:
        pytest.skip("needs root and unshare(1) to mount a small tmpfs in a private mount namespace")
    disk = tmp_path / "disk"
    disk.mkdir()
    script = (
        f"mount -t tmpfs -o size=256k tmpfs {disk} || exit 99; "
        f"dd if=/dev/zero of={disk}/filler bs=4k 2>/dev/null; "
        f'exec "$0" -m station.cli serve --port 0 --data {disk}/data'
    )
    env = {**os.environ, "STATION_API_TOKEN": TOKEN}
    done = subprocess.run(
        [unshare, "--mount", "--propagation", "private", "sh", "-c", script, sys.executable],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
        check=False,
    )
    if done.returncode == 99:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
    assert done.returncode == 1
    line = one_line(done)
    assert "cannot start:" in line
    assert "full" in line


def test_public_reads_on_an_address_other_than_loopback_are_warned_of(tmp_path: Path) -> None:
    done = serve("--public-read", "--host", "192.0.2.1", "--port", "0", "--data", str(tmp_path / "data"))
    lines = done.stderr.splitlines()
    assert any("reads are public (--public-read)" in line and "192.0.2.1" in line for line in lines), lines
    assert done.returncode == 1  # and then: not an address of this machine
    with socket.socket() as taken:  # on loopback: no warning (and then the port is in use)
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = str(taken.getsockname()[1])
        quiet = serve("--public-read", "--port", port, "--data", str(tmp_path / "d"))
    assert "the port is in use" in one_line(quiet)
