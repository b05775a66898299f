"""Measurement errors: each names what is wrong with the image and what to do about it."""

from __future__ import annotations

from collections.abc import Mapping

from station.vision._edges import Edge


class MeasurementError(ValueError):
    """An image could not be measured. ``code`` is a stable machine-readable reason."""

    code = "measurement_failed"

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


class InvalidImageError(MeasurementError):
    """The array is not an image this core can read (empty, wrong type or shape, too small)."""

    code = "invalid_image"


class ImageQualityError(MeasurementError):
    """The image is readable but unusable (blank, saturated)."""

    code = "image_quality"


class EdgeNotFoundError(MeasurementError):
    """Fewer than four groove edges were found."""

    code = "edges_not_found"

    def __init__(self, message: str, *, found: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.found = found


class GeometryError(MeasurementError):
    """Four edges were found but they do not form the artifact's cross."""

    code = "bad_geometry"


EDGE_LABELS: dict[Edge, str] = {
    "top": "the top edge of the horizontal groove",
    "bottom": "the bottom edge of the horizontal groove",
    "left": "the left edge of the vertical groove",
    "right": "the right edge of the vertical groove",
}


def describe_missing(problems: Mapping[Edge, str]) -> str:
    """'found 2 of 4 edges: the vertical groove was not found (left: ...; right: ...)'."""
    missing = set(problems)
    parts = []
    if {"top", "bottom"} <= missing:
        parts.append("the horizontal groove was not found")
    if {"left", "right"} <= missing:
        parts.append("the vertical groove was not found")
    whole = {e for pair in (("top", "bottom"), ("left", "right")) if set(pair) <= missing for e in pair}
    parts += [
        f"{EDGE_LABELS[e]} was not found"
        for e in ("top", "bottom", "left", "right")
        if e in missing and e not in whole
    ]
    details = "; ".join(f"{e}: {why}" for e, why in problems.items())
    hint = ""
    if len(missing) == 4:
        hint = " Is the crossed-groove artifact in view and in focus?"
    return f"found {4 - len(missing)} of 4 edges: {', '.join(parts)} ({details}).{hint}"


def rotated_too_far(
    rotation_deg: float, limit_deg: float, *, seen: str = "appears", digits: int = 0
) -> GeometryError:
    """The error for a cross turned beyond the mode's range, saying what to do."""
    return GeometryError(
        f"the cross {seen} rotated by {rotation_deg:.{digits}f} deg; this mode measures within "
        f"+/-{limit_deg:.0f} deg: turn the artifact (or the camera) toward the image axes"
    )
