"""The seed's validation (section 4): measure a set taken on the X-Y table and compare displacements."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.batch import FileResult
from station.compute import LocalBackend, MeasureBackend
from station.imagesets import ImageSet
from station.metrology import DisplacementComparison, compare_displacements
from station.vision import MeasureParams, series_centers_mm

#: How a series is scaled: one homography from all its images, or each image's own (the seed's).
CALIBRATIONS = ("series", "image")

FloatArray = npt.NDArray[np.float64]


class ValidationError(ValueError):
    """A validation cannot be computed (not a validation set, too few images measured)."""


@dataclass(frozen=True)
class ValidationResult:
    """Per-image results, measured displacements (um, artifact axes) and the comparison.

    ``center_error_px``: |measured - true centre| per image where the set has truth, else None.
    """

    image_set: ImageSet
    calibration: str
    results: tuple[FileResult, ...]
    measured_um: FloatArray
    used: npt.NDArray[np.bool_]
    comparison: DisplacementComparison
    center_error_px: FloatArray | None

    @property
    def failures(self) -> list[FileResult]:
        return [r for r in self.results if not r.ok]


def center_errors(image_set: ImageSet, results: tuple[FileResult, ...]) -> FloatArray | None:
    """Distance (px) between measured and true centre per measured image; None without truth."""
    if not image_set.truth:
        return None
    errs = []
    for r in results:
        truth = image_set.truth.get(r.file.rsplit("/", 1)[-1])
        if r.measurement is None or truth is None:
            continue
        errs.append(np.hypot(*(np.subtract(r.measurement.center_px, truth.center_px))))
    return np.asarray(errs, dtype=np.float64)


def validate(
    image_set: ImageSet,
    params: MeasureParams,
    *,
    jobs: int = 1,
    backend: MeasureBackend | None = None,
    calibration: str = "series",
) -> ValidationResult:
    """Measure every image of a validation set and compare measured with commanded displacements.

    Displacements are taken relative to the first image measured; images that fail are left out of the
    comparison (and listed in ``failures``). ``calibration``: ``series`` maps every image with one
    homography fitted from all of them; ``image`` uses each image's own (the seed's convention).
    The images are measured on ``backend`` (``station.compute``), else in a local pool of ``jobs``.
    """
    if calibration not in CALIBRATIONS:
        raise ValidationError(f"calibration {calibration!r} is not one of {', '.join(CALIBRATIONS)}")
    if image_set.displacements_um is None:
        raise ValidationError(f"{image_set.root}: no displacements.csv: not a validation set")
    if backend is None:
        with contextlib.closing(LocalBackend(jobs)) as local:
            results = tuple(local.measure(image_set.files, params))
    else:
        results = tuple(backend.measure(image_set.files, params))
    used = np.array([r.ok for r in results])
    if used.sum() < 3:
        raise ValidationError(
            f"only {int(used.sum())} of {len(results)} images were measured; at least 3 are needed"
        )
    measured = [r.measurement for r in results if r.measurement is not None]
    if calibration == "series":
        centers_mm = series_centers_mm(
            [m.center_px for m in measured], [m.corners_px for m in measured], params.groove_width_mm
        )
    else:
        centers_mm = np.array([m.center_mm for m in measured])
    measured_um = (centers_mm - centers_mm[0]) * 1000.0
    commanded = image_set.displacements_um[used]
    commanded = commanded - commanded[0]
    comparison = compare_displacements(commanded, measured_um)
    return ValidationResult(
        image_set, calibration, results, measured_um, used, comparison, center_errors(image_set, results)
    )
