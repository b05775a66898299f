"""How a ``sweep`` session's results are shown: the terminal's summary and the CSV's rows (one per
trial; over a selection, one per trial and one per trial and session)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from station.plans._present import flat


def summary(results: Mapping[str, Any]) -> str:
    return f"  {len(results['trials'])} trials; best: trial {results['best']}"


def rows(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    """One row per trial; over an archive selection, the trial's figures over every session
    (``session`` = ``all``) then one row per session."""
    out = []
    for t in results.get("trials") or []:
        if not isinstance(t, dict):
            continue
        per = t.get("sessions")
        if not isinstance(per, list):
            out.append(flat(t))
            continue
        out.append(flat({**{k: v for k, v in t.items() if k != "sessions"}, "session": "all"}))
        head = {"number": t.get("number"), "overrides": t.get("overrides") or {}}
        out.extend(flat({**head, **s}) for s in per if isinstance(s, dict))
    return out
