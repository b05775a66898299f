"""How a ``selftest`` session's results are shown: the terminal's summary and the CSV's rows (one per
controller check)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def summary(results: Mapping[str, Any]) -> str:
    identity = results.get("identity") or {}
    who = " ".join(str(v) for v in (identity.get("model"), identity.get("serial")) if v) or "the controller"
    lines = [f"  self-test of {who}: {'passed' if results.get('passed') else 'NOT passed'}"]
    lines += [f"  {c['name']}: {c['state']}: {c['summary']}" for c in results.get("controller_checks", [])]
    if results.get("latched"):
        lines.append("  the stop is latched (the halt check): acknowledge it at the station")
    return "\n".join(lines)


def rows(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    return [
        {"name": c["name"], "state": c["state"], "summary": c["summary"]}
        for c in results.get("controller_checks", [])
    ]
