"""Secrets never shown: one rule for configuration snapshots, database URLs, error messages and logs.

* A mapping entry whose name contains one of :data:`SECRET_WORDS` (case-insensitive: ``password``,
  ``DB_PASSWD``, ``apiKey``, ``Authorization``, ``client_credentials`` ...) has its value replaced by
  :data:`MASK`, whatever the value is.
* A URL (any string with ``scheme://``) keeps its shape but loses its password: the user part's
  (``postgresql://user:***@host/db``) and every query parameter whose name is secret
  (``?password=***``, ``&sslpassword=***``).
* :func:`scrub` replaces given secret values wherever they appear in a text (a driver's error message
  may echo a connection string).

Over-redaction is the safe side: a field named ``author`` is masked too.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import Any
from urllib.parse import parse_qsl, unquote

MASK = "***"
SECRET_WORDS = ("password", "passwd", "pwd", "secret", "token", "key", "auth", "credential", "private")
_URL = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*://[^\s'\"<>]+")


def is_secret_name(name: object) -> bool:
    """Whether a key, option or query parameter name suggests a secret."""
    lowered = str(name).lower()
    return any(word in lowered for word in SECRET_WORDS)


def _user_part_end(rest: str) -> tuple[int, int]:
    """Where the query starts in a URL after its ``scheme://``, and the ``@`` ending its user part (-1:
    none). The user part ends at the last ``@`` before the query: a password may hold ``/`` (SQLAlchemy
    reads everything up to the ``@`` as the password), so the host's end cannot be found first."""
    before_query = min((i for i in (rest.find("?"), rest.find("#")) if i >= 0), default=len(rest))
    return before_query, rest.rfind("@", 0, before_query)


def redact_url(url: str) -> str:
    """``url`` with the user part's password and every secret query parameter replaced by ``***``.

    Only those parts change: the rest is kept character for character (``sqlite:////abs/path`` too).
    """
    scheme, sep, rest = url.partition("://")
    if not sep:
        return url
    _, at = _user_part_end(rest)
    if at >= 0:
        user, has_password, _ = rest[:at].partition(":")
        if has_password:
            rest = f"{user}:{MASK}{rest[at:]}"
    path, qmark, query = rest.partition("?")
    if qmark:
        query, hash_mark, fragment = query.partition("#")
        fields = []
        for field in query.split("&"):
            name, eq, _ = field.partition("=")
            fields.append(f"{name}={MASK}" if eq and is_secret_name(unquote(name)) else field)
        rest = f"{path}?{'&'.join(fields)}{hash_mark}{fragment}"
    return f"{scheme}://{rest}"


def redact_text(text: str) -> str:
    """``text`` with every URL in it redacted (:func:`redact_url`)."""
    return _URL.sub(lambda m: redact_url(m.group(0)), text)


def redact(value: Any) -> Any:
    """A copy of ``value`` (mappings, lists, strings) with secrets masked (see the module notes)."""
    if isinstance(value, Mapping):
        return {k: (MASK if is_secret_name(k) else redact(v)) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [redact(v) for v in value]
    if isinstance(value, str) and "://" in value:
        return redact_text(value)
    return value


def url_secrets(url: str) -> list[str]:
    """The secret values a URL carries (its password, secret query values), to :func:`scrub` them from
    texts that may echo them (a database driver's error message)."""
    rest = url.partition("://")[2]
    before_query, user_end = _user_part_end(rest)
    found: list[str] = []
    if user_end >= 0:
        _, has_password, password = rest[:user_end].partition(":")
        if has_password and password:
            found += [password, unquote(password)]
    query = rest[before_query:].lstrip("?").split("#", 1)[0]
    found += [v for k, v in parse_qsl(query, keep_blank_values=True) if is_secret_name(k) and v]
    return found


def scrub(text: str, secrets: Iterable[str]) -> str:
    """``text`` with every URL redacted and each of ``secrets`` (non-empty values) replaced by ``***``."""
    out = redact_text(text)
    for secret in sorted({s for s in secrets if s}, key=len, reverse=True):
        out = out.replace(secret, MASK)
    return out
