"""One self-contained HTML page per session: header facts, tables, and the figures embedded as SVG.

Every string from the session (ids, parameters, identities, errors) passes through ``html.escape``; the
figures are embedded as ``data:image/svg+xml;base64`` images, so the page needs no other file and the SVGs'
own ids cannot collide with each other or with the page.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Mapping, Sequence

from station.kinds import KINDS
from station.reporting._session import Session, format_date
from station.reporting._table import Table

_CSS = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 60em; padding: 0 1em; color: #222; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 2em; }
table { border-collapse: collapse; margin: 1em 0 0.3em; font-size: 0.9em; }
caption { text-align: left; font-weight: 600; padding-bottom: 0.3em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: right; }
th:first-child, td:first-child { text-align: left; }
th { background: #f3f3f3; }
tr.marked td { font-weight: 700; background: #fff4d6; }
p.note { font-size: 0.85em; color: #555; margin: 0.2em 0; }
.state { display: inline-block; padding: 0.1em 0.6em; border-radius: 0.3em; background: #eee; }
.state-succeeded { background: #d8f0d8; }
.state-failed, .state-aborted, .state-interrupted { background: #f8d7d7; }
.banner { border: 2px solid #c33; background: #fdf0f0; padding: 0.6em 1em; margin: 1em 0; }
figure { margin: 1.5em 0; }
figure img { max-width: 100%; height: auto; border: 1px solid #eee; }
figcaption { font-size: 0.9em; color: #444; }
pre { background: #f6f6f6; padding: 0.6em; overflow-x: auto; font-size: 0.8em; }
details summary { cursor: pointer; }
"""

#: Tables shown collapsed (long, per-position detail).
_COLLAPSED = ("positions",)


def _title(kind: str) -> str:
    entry = KINDS.get(kind)
    return entry.title if entry is not None and entry.title else kind


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _banner(s: Session) -> str:
    if s.succeeded and s.problem is None:
        return ""
    ended = s.state in ("failed", "aborted", "stopped", "interrupted")
    verb = "did not succeed" if ended else "has not finished"
    parts = [f"This session {verb}: its state is <b>{_e(s.state)}</b>."]
    if s.error is not None:
        parts.append(f"Error: <b>{_e(s.error)}</b>.")
    if s.state == "interrupted":
        parts.append(f"Resume it with <code>station run --resume {_e(s.id)}</code>.")
    if s.raw_results is None:
        parts.append("It has no results; below are its facts as recorded.")
    elif s.problem is not None:
        parts.append(f"Its partial results could not be drawn ({_e(s.problem)}); they are shown as recorded.")
    elif s.failed_checks:
        parts.append(
            "Its results below failed their checks (see Checks): they are kept and shown, and are not a "
            "measurement to use."
        )
    else:
        parts.append("Its results below are partial.")
    return f'<div class="banner">{" ".join(parts)}</div>'


def _raw_results(s: Session) -> str:
    if s.problem is None or s.raw_results is None:
        return ""
    text = json.dumps(s.raw_results, indent=2, default=str, allow_nan=True)
    return f"<h2>Results as recorded</h2><pre>{_e(text)}</pre>"


def _figure(name: str, caption: str, svg: bytes) -> str:
    data = base64.b64encode(svg).decode("ascii")
    return (
        f'<figure id="fig-{_e(name)}"><img alt="{_e(caption)}" src="data:image/svg+xml;base64,{data}">'
        f'<figcaption>{_e(caption)} Files: <a href="{_e(name)}.png">{_e(name)}.png</a>, '
        f'<a href="{_e(name)}.svg">{_e(name)}.svg</a></figcaption></figure>'
    )


def render(s: Session, tables: Mapping[str, Table], figures: Sequence[tuple[str, str, bytes]]) -> str:
    """The page for session ``s``: ``tables`` by name, ``figures`` as (file stem, caption, SVG bytes)."""
    heading = _title(s.kind)
    if s.results_kind is not None and s.results_kind != s.kind:  # drawn as another kind's (a re-analysis)
        heading += f" ({_title(s.results_kind).lower()})"
    date = format_date(s.created_at)
    version = s.software.get("version", s.software.get("station"))
    facts = [
        f'<span class="state state-{_e(s.state)}">{_e(s.state)}</span>',
        f"session <b>{_e(s.id)}</b>",
        _e(s.kind),
        _e(date) if date else "date not recorded",
        f"software {_e(version)}" if version is not None else "software version not recorded",
    ]
    header = f"<h1>{_e(heading)}</h1><p>{' · '.join(facts)}</p>{_banner(s)}"
    about = "".join(tables[k].html() for k in ("session", "devices", "parameters") if k in tables)
    results = []
    for name, t in tables.items():
        if name in ("session", "devices", "parameters"):
            continue
        if name in _COLLAPSED:
            results.append(f"<details><summary>{_e(t.title)} ({len(t.rows)})</summary>{t.html()}</details>")
        else:
            results.append(t.html())
    results += [_figure(name, caption, svg) for name, caption, svg in figures]
    body = header + "<h2>Session</h2>" + about
    if results:
        body += "<h2>Results</h2>" + "".join(results)
    body += _raw_results(s)
    title = f"Session {s.id}: {s.kind} report"
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f'<meta name="viewport" content="width=device-width, initial-scale=1"><title>{_e(title)}</title>'
        f"<style>{_CSS}</style></head>\n<body>\n{body}\n</body></html>\n"
    )
