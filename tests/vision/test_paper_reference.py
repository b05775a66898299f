"""Paper mode is the seed's algorithm: its results on the benchmark images are pinned.

``data/paper_reference.json`` holds paper mode's results on the four image sets ``make bench`` renders
(random poses and the validation pattern, nominal and hard presets), computed on main before the
speed work of issue 12. Any change to paper mode's code must reproduce them within 1e-9 px: a faster
implementation may not move a single result.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from station.imageio import read_image
from station.vision import MeasurementError, MeasureParams, measure
from station.vision._kernels import available, kernels
from tests.vision.conftest import paper_reference

TOL_PX = 1e-9
#: Both implementations are pinned: the numpy reference and the compiled kernels (``_kernels``).
KERNELS = ["numpy", pytest.param("c", marks=pytest.mark.skipif(not available(), reason="not built"))]


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("set_name", list(paper_reference()["sets"]))
def test_paper_mode_reproduces_reference(bench_sets: Path, set_name: str, kernel: str) -> None:
    with kernels(kernel):
        _check_set(bench_sets, set_name)


def _check_set(bench_sets: Path, set_name: str) -> None:
    expected: dict[str, Any] = paper_reference()["results"][set_name]
    params = MeasureParams(mode="paper")
    files = sorted((bench_sets / set_name).glob("*.png"))
    assert [f.name for f in files] == sorted(expected)
    for f in files:
        want = expected[f.name]
        if "code" in want:  # the reference failed this image: the same error, for the same reason
            with pytest.raises(MeasurementError) as info:
                measure(read_image(f), params)
            assert info.value.code == want["code"], f"{set_name}/{f.name}"
            continue
        m = measure(read_image(f), params)
        np.testing.assert_allclose(m.center_px, want["center_px"], rtol=0, atol=TOL_PX, err_msg=f.name)
        np.testing.assert_allclose(m.corners_px, want["corners_px"], rtol=0, atol=TOL_PX, err_msg=f.name)
        np.testing.assert_allclose(m.lines, want["lines"], rtol=0, atol=TOL_PX, err_msg=f.name)
        # mm at 100 px/mm: 1e-9 px is 1e-11 mm
        np.testing.assert_allclose(m.center_mm, want["center_mm"], rtol=0, atol=1e-11, err_msg=f.name)
