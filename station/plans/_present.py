"""What the kinds' presentations share: number formats for the terminal's summary, a flat CSV row of a
nested object, and the failed checks' lines (``results.checks``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def um(v: Any, unit: str = "um") -> str:
    """A length with three decimals and its unit; "-" for none."""
    return "-" if v is None else f"{v:.3f} {unit}"


def flat(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """One CSV row of a nested object: ``a.b`` for nested keys, ``a[i]`` for lists of scalars."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(flat(v, f"{prefix}{k}."))
        elif isinstance(v, list | tuple) and all(not isinstance(x, dict | list) for x in v):
            for i, x in enumerate(v):
                out[f"{prefix}{k}[{i}]"] = x
        else:
            out[f"{prefix}{k}"] = v
    return out


def checks_summary(results: Mapping[str, Any]) -> str:
    """The checks that did not pass (a failed ``fail`` check failed the session)."""
    bad = [c for c in results.get("checks", []) if not c.get("passed")]
    lines = [
        f"  check {c['name']} {'FAILED' if c['severity'] == 'fail' else 'warning'}: {c['message']}"
        for c in bad
    ]
    return "\n".join(lines)
