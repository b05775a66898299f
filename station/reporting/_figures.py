"""The report's figures: those of the kind a session's results are drawn as (``station.kinds``: each
kind's report module)."""

from __future__ import annotations

from station.kinds import KINDS
from station.reporting._figure import NamedFigure
from station.reporting._model import Session


def results_figures(s: Session) -> list[NamedFigure]:
    """Every figure for a session's parsed results."""
    if s.results is None or s.results_kind is None:
        return []
    figures = KINDS[s.results_kind].figures
    return list(figures(s.results)) if figures is not None else []
