"""Issue 18, item 7 (table row 12): secrets are never shown. Every key of the list and a URL's passwords
(user part and query string) are masked in configuration snapshots, the record's URL, its errors and
what is logged."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import pytest

from station.config import StationConfig
from station.record import Record, RecordError
from station.redaction import MASK, redact, redact_url, scrub

SECRET = "hunter2-Zq9"
QUERY_SECRET = "q-secret-Zq9"


@pytest.mark.parametrize(
    "key",
    [
        "password", "DB_PASSWD", "pwd", "client_secret", "api_token", "apiKey", "Authorization", "auth",
        "credentials", "credential", "private_key", "x-private",
    ],
)  # fmt: skip
def test_every_secret_key_of_the_list_is_masked_at_any_depth(key: str) -> None:
    doc: dict[str, Any] = {"robot": {"options": {key: SECRET, "port": "/dev/ttyS0"}}, "list": [{key: 1}]}
    out = redact(doc)
    assert out["robot"]["options"][key] == MASK
    assert out["robot"]["options"]["port"] == "/dev/ttyS0"
    assert out["list"][0][key] == MASK
    assert doc["robot"]["options"][key] == SECRET  # a copy: the input is untouched


@pytest.mark.parametrize(
    ("url", "shown"),
    [
        (f"postgresql+psycopg://station:{SECRET}@db/rec", "postgresql+psycopg://station:***@db/rec"),
        (f"postgresql://db/rec?user=s&password={SECRET}", "postgresql://db/rec?user=s&password=***"),
        (f"postgresql://u:{SECRET}@h/d?sslpassword={QUERY_SECRET}&x=1", "postgresql://u:***@h/d?sslpassword=***&x=1"),
        ("postgresql://u:pa/ss@h/db", "postgresql://u:***@h/db"),
        ("sqlite:////srv/data/record.sqlite", "sqlite:////srv/data/record.sqlite"),
        ("postgresql://h/db?options=-csearch_path%3Dx", "postgresql://h/db?options=-csearch_path%3Dx"),
    ],
)  # fmt: skip
def test_a_urls_passwords_are_masked_in_the_user_part_and_the_query(url: str, shown: str) -> None:
    assert redact_url(url) == shown


def test_scrub_masks_urls_and_known_values_in_any_text() -> None:
    text = f"connect failed for postgresql://u:{SECRET}@h/d: password {SECRET} rejected"
    assert SECRET not in scrub(text, [SECRET])


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
