"""The repeatability figures lay out for any number of tests (1 to 8): nothing drawn is cut off at the
figure's edge, and the legend and the suptitle overlap no panel's text (the page showed the title and
legend of a ``joints=[1]`` session cut off)."""

from __future__ import annotations

import numpy as np
import pytest

from station.kinds.repeatability.report import repeatability_figure
from station.kinds.repeatability.results import RepeatabilityTest


def _test(joint: int, rng: np.random.Generator) -> RepeatabilityTest:
    points = rng.normal(0.0, 0.005, (30, 2)) + np.array([0.01, 0.27])
    return RepeatabilityTest(
        kind="joint",
        joint=joint,
        delta_deg=-10.0,
        points_mm=points.tolist(),
        barycentre_mm=points.mean(axis=0).tolist(),
        l_bar_mm=0.006,
        s_l_mm=0.003,
        rp_mm=0.015,
        rp_ci95_mm=[0.012, 0.018],
        n_cycles=30,
    )


@pytest.mark.parametrize("n", range(1, 9))
def test_repeatability_figure_fits_every_label_for_any_number_of_tests(n: int) -> None:
    rng = np.random.default_rng(n)
    named = repeatability_figure(
        {f"J{j}": _test(j % 6 + 1, rng) for j in range(1, n + 1)}, name="t", what="Joint tests"
    )
    fig = named.figure
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    frame = fig.bbox
    # each panel as drawn: its title, axis labels and the tick labels it shows
    panels = [(ax.get_title(), ax.get_tightbbox(renderer)) for ax in fig.axes if ax.get_visible()]
    assert len(panels) == n
    legend = fig.legends[0].get_window_extent(renderer)
    title = next(t for t in fig.texts if t.get_text().startswith("Joint tests")).get_window_extent(renderer)
    for what, box in [*panels, ("legend", legend), ("suptitle", title)]:
        assert box is not None
        assert frame.x0 - 0.5 <= box.x0, f"{what!r} is cut off at the left: {box}"
        assert box.x1 <= frame.x1 + 0.5, f"{what!r} is cut off at the right: {box}"
        assert frame.y0 - 0.5 <= box.y0, f"{what!r} is cut off at the bottom: {box}"
        assert box.y1 <= frame.y1 + 0.5, f"{what!r} is cut off at the top: {box}"
    for what, box in panels:
        assert box is not None
        assert not box.overlaps(legend), f"the legend covers panel {what!r}"
        assert not box.overlaps(title), f"the suptitle covers panel {what!r}"
