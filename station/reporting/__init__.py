"""Session reports (issue: sessions, item 8): the seed's tables and figures, and one HTML page.

``write_report(session, out_dir)`` writes the figures as PNG and SVG and a self-contained HTML report;
``text_tables(session)`` gives the same tables as plain text for the command line. ``session`` is the
record's mapping (``id``, ``kind``, ``state``, ``created_at``, ``params``, ``identities``, ``software``,
``results``, optionally ``error``); each kind's results model (``station/kinds/<kind>/results.py``)
gives the results' shapes.

The package holds the shared machinery (``_table``, ``_figure``, ``_session``, ``_html``), which the
kinds' report modules use, and the writer, which asks the kinds' registry; the writer is loaded when
first asked for, so that a kind importing the machinery never loads the registry it belongs to.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from station.reporting._session import ReportError

if TYPE_CHECKING:
    from station.reporting._write import PNG_DPI, ReportFiles, text_tables, write_report

_WRITER = ("PNG_DPI", "ReportFiles", "text_tables", "write_report")


def __getattr__(name: str) -> Any:
    if name in _WRITER:
        from station.reporting import _write

        return getattr(_write, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["PNG_DPI", "ReportError", "ReportFiles", "text_tables", "write_report"]
