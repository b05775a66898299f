"""How a ``sweep`` session's results are shown: the terminal's summary and the CSV's rows (one per
trial)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from station.plans._present import flat


def summary(results: Mapping[str, Any]) -> str:
    return f"  {len(results['trials'])} trials; best: trial {results['best']}"


def rows(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    return [flat(t) for t in results.get("trials") or [] if isinstance(t, dict)]
