"""The allocator tuning the command line applies (glibc's mallopt through ctypes)."""

from __future__ import annotations

import platform

import pytest

from station.runtime import tune_allocator


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc", reason="glibc only")
def test_tuning_applies_on_glibc_and_is_idempotent() -> None:
    assert tune_allocator() is True
    assert tune_allocator() is True
