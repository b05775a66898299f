"""``write_report``: a session's tables, figures (PNG + SVG) and one HTML page, written into a folder."""

from __future__ import annotations

import io
import os
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from station.reporting._figures import results_figures
from station.reporting._html import render
from station.reporting._model import ReportError, parse_session
from station.reporting._tables import all_tables

#: PNG resolution: 6.4 in wide figures become 960 px, sharp on screen and in print.
PNG_DPI = 150


@dataclass(frozen=True)
class ReportFiles:
    """What ``write_report`` wrote: the HTML page, every figure file (PNG then SVG per figure), and the
    plain-text tables by name (the same as ``text_tables``)."""

    html: Path
    figures: tuple[Path, ...]
    tables: dict[str, str]


def text_tables(session: Mapping[str, Any]) -> dict[str, str]:
    """Plain-text tables of a session, by name, in report order.

    Names: ``session``, ``devices``, ``parameters``, then per kind ``validation`` and ``positions``;
    ``repeatability`` (the seed's Table 2); ``sweep`` (Table 1) and ``seed_table_1`` when the trials are
    the seed's; ``relative_error``, ``residuals``, ``estimates``, ``identifiability``, ``structural`` and
    (when the pose set leaves directions undetermined) ``deficiencies`` for a calibration. A session
    without results has only the first three. ReportError if it is malformed.
    """
    return {name: t.text() for name, t in all_tables(parse_session(session)).items()}


def _render(fig: Figure, fmt: str) -> bytes:
    buf = io.BytesIO()
    if fmt == "svg":
        fig.savefig(buf, format="svg", metadata={"Date": None})
    else:
        fig.savefig(buf, format="png", dpi=PNG_DPI)
    return buf.getvalue()


def _write_atomic(path: Path, data: bytes) -> None:
    """Write to a temporary name, fsync, rename: a reader never sees half a file.

    The temporary name is unique (created exclusively, beside ``path`` so that the rename stays on one
    file system): writers of the same report at once, in threads or processes (the service and
    ``station report``), never write into each other's file or rename it from under each other; the
    last rename wins, with a whole file. Its permissions follow the umask, as a plain ``open`` does.
    """
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.tmp")
    try:
        with open(tmp, "xb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise ReportError(
            f"cannot write {path}: {exc.strerror or exc}; check the folder and free space"
        ) from exc


def write_report(session: Mapping[str, Any], out_dir: Path) -> ReportFiles:
    """Write a session's report into ``out_dir`` (created if needed) and say what was written.

    Files: ``report.html`` (self-contained: tables as HTML, figures embedded as SVG), and per figure
    ``NAME.png`` and ``NAME.svg``: ``validation-raw`` and ``validation-parallelogram`` (seed Figs. 14-15),
    ``repeatability`` (Figs. 16-17) and ``repeatability-rp``, ``sweep`` (Table 1 as bars), or
    ``calibration-residuals``, ``calibration-parameters`` and ``calibration-singular-values``. A session
    that did not succeed gets a report that says so, with its error and whatever results it has.

    Raises
    ------
    ReportError
        The mapping is not a session, a succeeded session's results are malformed (the message names
        the field), or a file cannot be written.
    """
    s = parse_session(session)
    tables = all_tables(s)
    figures = results_figures(s)
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ReportError(f"cannot create the report folder {out}: {exc.strerror or exc}") from exc
    paths: list[Path] = []
    embedded: list[tuple[str, str, bytes]] = []
    for nf in figures:
        svg = _render(nf.figure, "svg")
        nf.figure.set_layout_engine("none")  # laid out by the first rendering; the PNG reuses it
        for fmt, data in (("png", _render(nf.figure, "png")), ("svg", svg)):
            path = out / f"{nf.name}.{fmt}"
            _write_atomic(path, data)
            paths.append(path)
        embedded.append((nf.name, nf.caption, svg))
    page = out / "report.html"
    _write_atomic(page, render(s, tables, embedded).encode("utf-8"))
    return ReportFiles(page, tuple(paths), {name: t.text() for name, t in tables.items()})
