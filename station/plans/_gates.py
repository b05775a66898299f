"""Gates: each plan's analysis checks its result against what is physically possible.

A check is ``{"name", "passed", "value", "limit", "severity", "message"}`` in ``results.checks``.
``severity`` is ``"fail"`` or ``"warn"``: a session whose results fail a ``fail`` check ends ``failed``
with the failed checks' messages as its error (everything captured and computed is kept, and shown
marked as failed); a failed ``warn`` check keeps ``succeeded`` and is shown. ``value`` and ``limit``
are in the unit the check's name or message gives (``limit`` is a number, or ``[low, high]`` for a
band). A check that cannot be computed (no value) fails.

A plan that can tell during the session that its result cannot be right raises :class:`GateError`
from its ``check_progress`` (see :class:`~station.plans.Plan`): the runner stops the session at once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

Severity = Literal["fail", "warn"]


class GateError(ValueError):
    """The session's result cannot be right (a gate failed while it ran): the message says what to do.

    (A ValueError, as ``station.plans.PlanError`` is: the runner fails the session with its message.)"""


@dataclass(frozen=True)
class Check:
    """One gate's verdict on a result."""

    name: str
    passed: bool
    value: float | None
    limit: float | tuple[float, float]
    severity: Severity
    message: str

    def to_json(self) -> dict[str, Any]:
        limit: float | list[float] = list(self.limit) if isinstance(self.limit, tuple) else self.limit
        return {
            "name": self.name,
            "passed": self.passed,
            "value": self.value,
            "limit": limit,
            "severity": self.severity,
            "message": self.message,
        }


def _finite(value: float | None) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


def at_most(name: str, value: float | None, limit: float, *, severity: Severity, ok: str, bad: str) -> Check:
    """Passed when ``value <= limit``; ``ok`` / ``bad`` are the messages (``{value}`` and ``{limit}``
    are filled in)."""
    v = _finite(value)
    passed = v is not None and v <= limit
    text = (ok if passed else bad).format(value=_fmt(v), limit=_fmt(limit))
    return Check(name, passed, v, limit, severity, text)


def at_least(name: str, value: float | None, limit: float, *, severity: Severity, ok: str, bad: str) -> Check:
    """Passed when ``value >= limit`` (messages as :func:`at_most`)."""
    v = _finite(value)
    passed = v is not None and v >= limit
    text = (ok if passed else bad).format(value=_fmt(v), limit=_fmt(limit))
    return Check(name, passed, v, limit, severity, text)


def within(
    name: str, value: float | None, band: tuple[float, float], *, severity: Severity, ok: str, bad: str
) -> Check:
    """Passed when ``low <= value <= high`` (messages as :func:`at_most`; ``{low}``, ``{high}`` too)."""
    v = _finite(value)
    lo, hi = band
    passed = v is not None and lo <= v <= hi
    text = (ok if passed else bad).format(value=_fmt(v), low=_fmt(lo), high=_fmt(hi))
    return Check(name, passed, v, (lo, hi), severity, text)


def _fmt(v: float | None) -> str:
    return "(none)" if v is None else f"{v:.6g}"


def failed_checks(results: Mapping[str, Any] | None) -> list[Mapping[str, Any]]:
    """The ``fail`` checks of ``results.checks`` that did not pass."""
    if not results:
        return []
    checks = results.get("checks")
    if not isinstance(checks, Sequence):
        return []
    return [
        c
        for c in checks
        if isinstance(c, Mapping) and c.get("severity") == "fail" and c.get("passed") is not True
    ]


def verdict(results: Mapping[str, Any] | None) -> str | None:
    """The session's error when its results fail a gate (the failed checks' messages), else None."""
    bad = failed_checks(results)
    if not bad:
        return None
    return "the results failed their checks: " + "; ".join(str(c.get("message")) for c in bad)


def checks_json(checks: Sequence[Check]) -> list[dict[str, Any]]:
    return [c.to_json() for c in checks]
