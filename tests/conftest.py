"""Shared fixtures and the project's test policy.

* Warnings are errors (pyproject); randomness is seeded; no wall-clock assertions.
* ``needs_system(what, ok)``: a test that needs a system library skips where it is missing, but
  under ``CI=true`` a missing library is a failure (CI must install what the tests need).
* ``--hardware``: tests marked ``hardware`` run only when asked for.
"""

from __future__ import annotations

import os

import pytest


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--hardware", action="store_true", help="run tests that need real hardware")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--hardware"):
        return
    skip = pytest.mark.skip(reason="needs real hardware: run with --hardware")
    for item in items:
        if "hardware" in item.keywords:
            item.add_marker(skip)


def in_ci() -> bool:
    return os.environ.get("CI", "").lower() in {"1", "true", "yes"}


def needs_system(what: str, available: bool, hint: str = "") -> None:
    """Skip (locally) or fail (under CI=true) when the system library ``what`` is missing."""
    if available:
        return
    message = f"missing system library: {what}" + (f" ({hint})" if hint else "")
    if in_ci():
        pytest.fail(message + "; CI must install it (tools/apt-packages.txt)", pytrace=False)
    pytest.skip(message)
