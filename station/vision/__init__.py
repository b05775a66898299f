"""The measurement core: pure functions from an image and parameters to a Measurement.

Imports nothing of the project (checked by tools/check_layers.py). Stages, each testable alone:
``apply_filter`` (3.2.1), ``directional_responses``/``apply_threshold`` (3.2.2-3), ``segment_edge``
(3.2.4 TestBox), ``intensity_moment`` (eqs. 7-8), ``recursive_fit`` (3.2.4), ``vertices``,
``square_homography`` and ``centre`` (3.2.5-3.2.6).
"""

from station.vision._edges import EDGES, Edge, apply_threshold, directional_responses
from station.vision._errors import (
    EdgeNotFoundError,
    GeometryError,
    ImageQualityError,
    InvalidImageError,
    MeasurementError,
)
from station.vision._filters import apply_filter, gauss_kernel_7x7
from station.vision._geometry import (
    apply_homography,
    centre,
    intersect,
    normal_form,
    square_homography,
    vertices,
)
from station.vision._image import check_quality, image_bit_depth, to_gray8
from station.vision._linefit import RecursiveFit, recursive_fit
from station.vision._measure import measure
from station.vision._moment import intensity_moment
from station.vision._params import (
    NOMINAL_GROOVE_WIDTH_MM,
    SEED_GAUSS_SIGMA_PX,
    MeasureParams,
    Mode,
    field_name,
    field_names,
    parse_assignments,
)
from station.vision._result import EdgeFit, Measurement
from station.vision._ruler_errors import (
    CodeInconsistentError,
    CodeUnreadableError,
    OffRulerError,
    TooFewGraduationsError,
)
from station.vision._ruler_measure import measure_ruler
from station.vision._ruler_params import RulerParams, parse_ruler_assignments
from station.vision._ruler_result import RulerMeasurement
from station.vision._ruler_spec import RulerCode, RulerSpec
from station.vision._sanity import IncompleteCrossError, MultipleCrossingsError, check_single_cross
from station.vision._series import series_centers_mm, series_homography
from station.vision._testbox import acceptance_mask, segment_edge, testbox_scan

__all__ = [
    "EDGES",
    "NOMINAL_GROOVE_WIDTH_MM",
    "SEED_GAUSS_SIGMA_PX",
    "CodeInconsistentError",
    "CodeUnreadableError",
    "Edge",
    "EdgeFit",
    "EdgeNotFoundError",
    "GeometryError",
    "ImageQualityError",
    "IncompleteCrossError",
    "InvalidImageError",
    "MeasureParams",
    "Measurement",
    "MeasurementError",
    "Mode",
    "MultipleCrossingsError",
    "OffRulerError",
    "RecursiveFit",
    "RulerCode",
    "RulerMeasurement",
    "RulerParams",
    "RulerSpec",
    "TooFewGraduationsError",
    "acceptance_mask",
    "apply_filter",
    "apply_homography",
    "apply_threshold",
    "centre",
    "check_quality",
    "check_single_cross",
    "directional_responses",
    "field_name",
    "field_names",
    "gauss_kernel_7x7",
    "image_bit_depth",
    "intensity_moment",
    "intersect",
    "measure",
    "measure_ruler",
    "normal_form",
    "parse_assignments",
    "parse_ruler_assignments",
    "recursive_fit",
    "segment_edge",
    "series_centers_mm",
    "series_homography",
    "square_homography",
    "testbox_scan",
    "to_gray8",
    "vertices",
]
