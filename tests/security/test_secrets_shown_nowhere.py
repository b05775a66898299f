"""Issue 18, item 7 (table row 12): no password of the record's URL (user part or query) and no value of
a secret configuration key (password, passwd, pwd, secret, token, key, auth, credential(s), private)
is shown: not in the configuration snapshot kept with each session and shown by ``GET /station``, not
in the record's URL, not in its errors, not in what is logged. (``GET /station`` itself:
``tests/api/test_import_and_lock.py``.)"""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from station.config import StationConfig
from station.record import Record, RecordError

SECRET = "hunter2-Zq9"
QUERY_SECRET = "q-secret-Zq9"


def test_the_configuration_snapshot_has_no_secret() -> None:
    """The copy kept with every session (and shown by ``GET /station``)."""
    config = StationConfig.model_validate(
        {
            "database": f"postgresql+psycopg://station@db/rec?password={QUERY_SECRET}",
            "camera": {
                "driver": "aravis",
                "options": {"camera_id": "Basler-1", "passwd": SECRET, "pwd": SECRET, "auth": SECRET},
            },
            "robot": {
                "driver": "crs_a465",
                "options": {"credentials": SECRET, "private": SECRET},
                "reference_joints_deg": [0, 30, 60, 0, 90, 0],
            },
        }
    )
    text = repr(config.snapshot())
    assert SECRET not in text
    assert QUERY_SECRET not in text
    assert "Basler-1" in text


def test_the_records_url_and_errors_show_no_password(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A server that cannot be reached: the error names the record with its passwords masked, and
    whatever the driver says about the connection is scrubbed of them too."""
    url = (
        f"postgresql+psycopg://station:{SECRET}@/postgres?host={tmp_path}/no-server"
        f"&password={QUERY_SECRET}&connect_timeout=2"
    )
    caplog.set_level(logging.DEBUG)
    with pytest.raises(RecordError) as refused:
        Record(tmp_path / "data", url)
    message = str(refused.value)
    assert "cannot open the record at postgresql+psycopg://station:***@/postgres" in message
    assert SECRET not in message
    assert QUERY_SECRET not in message
    assert all(SECRET not in r.getMessage() and QUERY_SECRET not in r.getMessage() for r in caplog.records)


def test_a_bad_url_is_named_without_its_password(tmp_path: Path) -> None:
    with pytest.raises(RecordError) as refused:
        Record(tmp_path / "data", f"nonsense://u:{SECRET}@h/d?password={QUERY_SECRET}")
    assert SECRET not in str(refused.value)
    assert QUERY_SECRET not in str(refused.value)
