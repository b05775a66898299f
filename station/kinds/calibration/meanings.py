"""What each figure of a calibration's results measures, and over which region of the cell it holds
(issue 22, item 6): data, shown beside the figures by ``--json`` (``results.measures``) and the report,
so that a headline near the artifacts is never read as the arm's accuracy everywhere.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

FIGURES: dict[str, dict[str, str]] = {
    "relative_error_um": {
        "meaning": "mean in-plane distance (um) between two held-out configurations' positions of one "
        "crossing (the same point: ideally 0), camera turns and joint solutions apart; a model wrong in "
        "its lengths or its scale can still bring them together",
        "region": "near the artifacts: within a few millimetres of each crossing, at the poses that see it",
    },
    "absolute_error_um": {
        "meaning": "mean magnitude (um) of the arm's predicted displacement between two held-out ruler "
        "frames 10 mm or more apart minus the ruler's certified reading of it: lengths, hence the scale",
        "region": "along the rulers: displacements up to their length (250 mm) over the poses that see them",
    },
    "magnification": {
        "meaning": "the camera's image scale (px/mm) as the rulers' certified pitch gives it, with its "
        "95 % interval; every length the images give scales with it",
        "region": "the capture plane: the working distance in front of the camera",
    },
}
"""Each figure's meaning and region, by its key in the results."""


def measures_of(results: Mapping[str, Any]) -> dict[str, dict[str, str]]:
    """The meanings of the figures ``results`` has (a calibration without rulers: the relative error's)."""
    return {k: dict(v) for k, v in FIGURES.items() if results.get(k) is not None}


__all__ = ["FIGURES", "measures_of"]
