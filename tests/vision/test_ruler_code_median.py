"""The code cells' median over the track's sub-strips (``_ruler_code._row_nanmedian``): numpy's
``nanmedian`` along the rows, element for element, without its per-row loop."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from station.vision._ruler_code import _row_nanmedian


@pytest.mark.parametrize("columns", [1, 2, 3, 4, 5])
def test_the_rows_median_is_numpy_s_nanmedian(columns: int) -> None:
    rng = np.random.default_rng(columns)
    q = rng.normal(size=(4000, columns))
    q[rng.uniform(size=q.shape) < 0.3] = np.nan  # unread sub-strips, and some rows of them only
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # numpy warns of the all-NaN rows
        ref = np.nanmedian(q, axis=1)
    got = _row_nanmedian(q)
    assert np.isnan(ref).any()
    assert_array_equal(got, ref)  # NaN where numpy's is, the same values elsewhere
