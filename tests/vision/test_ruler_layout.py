"""The ruler's layout: the strips it cuts the pattern into tile their bands exactly."""

from __future__ import annotations

import numpy as np

from station.vision._ruler_layout import _tip_zone


def test_tip_zone_strips_tile_the_zone_without_overlap_by_rounding() -> None:
    # the bounds and strip width of a frame from a calibration's ruler configurations, whose strips
    # overlapped by one ulp (arange's starts against start + width) and made the measurement raise a
    # bare ValueError instead of measuring
    lo, hi, px = -3.3962845298902473, -3.0233439230987775, 0.019628452989024714
    strips = _tip_zone(lo, hi, px, lambda a, b: (-1.5998491232815677, 10.013121481533647))
    assert strips is not None
    table = strips.table
    assert table[0, 0] == lo
    assert table[-1, 1] == hi
    np.testing.assert_array_equal(table[1:, 0], table[:-1, 1])  # each strip starts where the last ends
    assert np.all(table[:, 1] > table[:, 0])
    np.testing.assert_allclose(np.diff(table[:, 0]), px, rtol=1e-9)
