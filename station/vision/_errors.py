"""Measurement errors: each names what is wrong with the image and what to do about it."""

from __future__ import annotations


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
