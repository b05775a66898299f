"""The report's table machinery: a titled table rendered as text (the CLI) or HTML (the report), and the
tables every session has (its facts, devices, parameters, checks, captures not measured)."""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from station.plans._results import Check
from station.reporting._session import Session, format_date, format_value
from station.text_tables import table


@dataclass(frozen=True)
class Table:
    """A titled table of text cells; ``marked`` rows (e.g. the best trial) are emphasised in HTML."""

    title: str
    headers: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    notes: tuple[str, ...] = ()
    marked: frozenset[int] = frozenset()

    def text(self) -> str:
        parts = [self.title, table(self.headers, self.rows)]
        if self.notes:
            parts.append("\n".join(self.notes))
        return "\n".join(parts)

    def html(self) -> str:
        e = html.escape
        head = "".join(f"<th>{e(h)}</th>" for h in self.headers)
        body = []
        for i, row in enumerate(self.rows):
            cls = ' class="marked"' if i in self.marked else ""
            cells = "".join(f"<td>{e(c)}</td>" for c in row)
            body.append(f"<tr{cls}>{cells}</tr>")
        notes = "".join(f'<p class="note">{e(n)}</p>' for n in self.notes)
        return (
            f"<table><caption>{e(self.title)}</caption><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>{notes}"
        )


def make_table(title: str, headers: Sequence[str], rows: Sequence[Sequence[str]], *notes: str) -> Table:
    return Table(title, tuple(headers), tuple(tuple(r) for r in rows), tuple(n for n in notes if n))


def session_table(s: Session) -> Table:
    """Who, what, when: id, kind, state, date, software, source session and error."""
    rows = [
        ("id", s.id),
        ("kind", s.kind),
        ("state", s.state),
        ("created", format_date(s.created_at)),
        ("software", ", ".join(f"{k} {format_value(v)}" for k, v in s.software.items()) or "not recorded"),
    ]
    if s.source_session is not None:
        rows.append(("source session", s.source_session))
    if s.error is not None:
        rows.append(("error", s.error))
    return make_table("Session", ("field", "value"), rows)


def parameters_table(s: Session) -> Table:
    """One row per parameter; groups (the plan's, the measurement's) flattened as ``group.name``."""
    rows = []
    for k, v in s.params.items():
        if isinstance(v, dict) and v:
            rows += [(f"{k}.{name}", format_value(value)) for name, value in v.items()]
        else:
            rows.append((str(k), format_value(v)))
    return make_table("Parameters", ("parameter", "value"), rows or [("(none recorded)", "")])


def devices_table(s: Session) -> Table:
    """One row per device; one column per identity field (model, serial or port, firmware, ...)."""
    fields: list[str] = []
    for ident in s.identities.values():
        if isinstance(ident, dict):
            fields += [str(k) for k in ident if str(k) not in fields]
    rows = []
    for name, ident in s.identities.items():
        if isinstance(ident, dict):
            rows.append([str(name), *(format_value(ident.get(f, "")) for f in fields)])
        else:
            rows.append([str(name), format_value(ident), *([""] * (len(fields) - 1))])
    if not rows:
        return make_table("Devices", ("device", "identity"), [("(none recorded)", "")])
    return make_table("Devices", ("device", *(fields or ["identity"])), rows)


def failures_table(failures: Sequence[Mapping[str, Any]], tests: Sequence[str] | None = None) -> Table:
    """Captures whose measurement failed: where (test, step, frame, capture) and why."""
    rows = []
    for i, f in enumerate(failures):
        error = format_value(f.get("error") or "not measured") + (f" ({f['code']})" if f.get("code") else "")
        where = [format_value(f.get(k)) for k in ("step_index", "frame_index", "capture_id")]
        rows.append([*([tests[i]] if tests is not None else []), *where, error])
    headers = [*(["test"] if tests is not None else []), "step", "frame", "capture", "error"]
    return make_table("Captures not measured", headers, rows, "kept in the record; left out of the results")


def checks_table(checks: Sequence[Check]) -> Table:
    """The gates' verdicts: a failed ``fail`` check failed the session, a failed ``warn`` check is shown."""
    rows = []
    for c in checks:
        verdict = "passed" if c.passed else ("FAILED" if c.severity == "fail" else "warning")
        if isinstance(c.limit, tuple):
            limit = f"[{c.limit[0]:.6g}, {c.limit[1]:.6g}]"
        else:
            limit = "" if c.limit is None else f"{c.limit:.6g}"
        value = "-" if c.value is None else f"{c.value:.6g}"
        rows.append([c.name, verdict, value, limit, c.severity, c.message])
    return make_table(
        "Checks",
        ("check", "verdict", "value", "limit", "severity", "message"),
        rows,
        "each result checked against what is physically possible; a failed 'fail' check fails the session",
    )


def tuples(rows: Sequence[Sequence[str]]) -> tuple[tuple[str, ...], ...]:
    return tuple(tuple(r) for r in rows)
