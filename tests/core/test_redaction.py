"""Issue 18, item 7 (table row 12): secrets are never shown. Every key of the list and a URL's passwords
(user part and query string) are masked in configuration snapshots, the record's URL, its errors and
what is logged."""

from __future__ import annotations

from typing import Any

import pytest

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
