"""Session reports (issue: sessions, item 8): the seed's tables and figures, and one HTML page.

``write_report(session, out_dir)`` writes the figures as PNG and SVG and a self-contained HTML report;
``text_tables(session)`` gives the same tables as plain text for the command line. ``session`` is the
record's mapping (``id``, ``kind``, ``state``, ``created_at``, ``params``, ``identities``, ``software``,
``results``, optionally ``error``); see ``_model.py`` for the results' shapes.
"""

from station.reporting._model import ReportError
from station.reporting._write import PNG_DPI, ReportFiles, text_tables, write_report

__all__ = ["PNG_DPI", "ReportError", "ReportFiles", "text_tables", "write_report"]
