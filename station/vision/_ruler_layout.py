"""Where the ruler measurement looks: the strips of one pass over the pixels.

Across the ruler (``t``, periods), from the lower tips up: the phase strips of the lines' lower
part, the code track's sub-strips, the phase strips of the upper part; and apart (they overlap the
phase strips), the two tip zones in strips one pixel wide. Along the ruler the phase strips cover
every part of them in the frame, in windows of a whole number of periods, ``window_periods`` or
fewer so that a strip holds at least three (a window at the frame's edge holds fewer pixels); the
code and tip strips the stretch over which they are wholly inside the frame, the code in bins of
1/64 period, the tip zones in bins of 1/32 period.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.vision._ruler_bins import Strips
from station.vision._ruler_frame import RulerFrame
from station.vision._ruler_params import RulerParams
from station.vision._ruler_phase import BINS_PER_WINDOW

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Sub-strips across the code track (a cell's value is their median).
CODE_SUBSTRIPS = 3
CODE_BINS_PER_PERIOD = 64
TIP_BINS_PER_PERIOD = 32
#: Extent of a tip zone beyond the lines' tips and inside them (px): symmetric enough about the
#: step that the fit of its blurred profile is not pulled by a mismatch of the profile's shape.
TIP_OUTSIDE_PX = 10.0
TIP_INSIDE_PX = 9.0


@dataclass(frozen=True)
class Plan:
    """The strips of one pass and what each is for (row numbers in ``strips.table``).

    ``tips``: the lower and upper tip zones, each its own strips (they overlap the phase strips, so
    they are binned apart), or None outside the full pass or where a zone is not in the frame.
    """

    strips: Strips
    phase_rows: tuple[int, ...]
    window_starts: FloatArray
    window_lengths: FloatArray
    window_strip: IntArray
    code_rows: tuple[int, ...]
    tips: tuple[Strips | None, Strips | None]

    def rows(self, bins: FloatArray, rows: tuple[int, ...]) -> FloatArray:
        """The bins of the given strips, in order."""
        offsets = self.strips.offsets
        if not rows:
            return np.zeros((0, bins.shape[1]))
        return np.concatenate([bins[offsets[r] : offsets[r + 1]] for r in rows])

    def row_ids(self, rows: tuple[int, ...]) -> IntArray:
        """For each bin of ``rows`` (as ``rows()`` returns them), the position of its strip in ``rows``."""
        counts = self.strips.table[list(rows), 4].astype(np.int64)
        return np.repeat(np.arange(len(rows)), counts)


def plan(
    frame: RulerFrame, period_px: float, params: RulerParams, shape: tuple[int, int], *, full: bool
) -> Plan:
    """The strips for one pass: the phase strips only, or (``full``) with the code and the tips."""
    spec = params.ruler
    height, width = shape
    px = 1.0 / period_px  # one pixel, in periods
    margin = params.margin_px * px
    length = float(params.window_periods)
    rows: list[tuple[float, float, float, float, float, str]] = []
    half = spec.line_length_mm / 2 / spec.pitch_mm
    parts = [(lo / spec.pitch_mm, hi / spec.pitch_mm) for lo, hi in spec.line_segments_mm]
    code_lo, code_hi = (v / spec.pitch_mm for v in spec.code_track_mm)
    part_edges = []
    for lo, hi in parts:
        a, b = lo + margin, hi - margin
        count = max(1, round((b - a) / (params.strip_px * px))) if b - a >= 2 * px else 0
        part_edges.append(np.linspace(a, b, count + 1) if count else np.zeros(0))
    code_edges = np.linspace(code_lo + margin, code_hi - margin, CODE_SUBSTRIPS + 1)
    tip_bounds = [-half - TIP_OUTSIDE_PX * px, -half + TIP_INSIDE_PX * px, half - TIP_INSIDE_PX * px]
    tip_bounds.append(half + TIP_OUTSIDE_PX * px)
    # every line t = const the plan asks about, in one vectorised call
    asked = np.concatenate([*part_edges, code_edges, tip_bounds])
    lows, highs = frame.s_ranges(asked, width, height)
    known = {float(t): (float(lo), float(hi)) for t, lo, hi in zip(asked, lows, highs, strict=True)}

    def one(t: float) -> tuple[float, float] | None:
        lo, hi = known[float(t)]
        return None if math.isnan(lo) else (lo, hi)

    def stretch(lo: float, hi: float) -> tuple[float, float] | None:
        first, second = one(lo), one(hi)
        if first is None or second is None:
            return None
        a, b = max(first[0], second[0]), min(first[1], second[1])
        return (a, b) if b > a else None

    def reach(lo: float, hi: float) -> tuple[float, float] | None:
        spans = [r for r in (one(lo), one(hi)) if r]
        return (min(r[0] for r in spans), max(r[1] for r in spans)) if spans else None

    for number, edges in enumerate(part_edges):
        for s_lo_t, s_hi_t in itertools.pairwise(edges):
            # every part of the strip in the frame: windows partly outside it hold fewer pixels
            span = reach(float(s_lo_t), float(s_hi_t))
            if span is None:
                continue
            # whole periods (a window's phase is then at its centroid whatever the frame's residual
            # slope), at most window_periods and at least 3 windows where the span allows, centred
            size = float(min(length, max(1, math.floor((span[1] - span[0]) / 3))))
            windows = int((span[1] - span[0]) // size)
            if windows < 1:
                continue
            start = span[0] + 0.5 * ((span[1] - span[0]) - windows * size)
            per = BINS_PER_WINDOW / size
            rows.append((float(s_lo_t), float(s_hi_t), start, per, windows * BINS_PER_WINDOW, "phase"))
        if full and number == 0:
            for a2, b2 in itertools.pairwise(code_edges):
                span = stretch(float(a2), float(b2))
                if span is not None:
                    bins = math.ceil((span[1] - span[0]) * CODE_BINS_PER_PERIOD)
                    rows.append((float(a2), float(b2), span[0], CODE_BINS_PER_PERIOD, bins, "code"))
    table = np.array([r[:5] for r in rows], dtype=np.float64).reshape(-1, 5)
    kinds = [r[5] for r in rows]
    phase = tuple(i for i, k in enumerate(kinds) if k == "phase")
    starts: list[float] = []
    lengths: list[float] = []
    strip: list[int] = []
    for number, i in enumerate(phase):
        count = int(table[i, 4]) // BINS_PER_WINDOW
        size = BINS_PER_WINDOW / table[i, 3]
        starts += [table[i, 2] + j * size for j in range(count)]
        lengths += [size] * count
        strip += [number] * count
    tips: tuple[Strips | None, Strips | None] = (None, None)
    if full:
        tips = (
            _tip_zone(tip_bounds[0], tip_bounds[1], px, stretch),
            _tip_zone(tip_bounds[2], tip_bounds[3], px, stretch),
        )
    return Plan(
        strips=Strips(table) if len(table) else Strips(np.array([[0.0, 1.0, 0.0, 1.0, 1.0]])),
        phase_rows=phase,
        window_starts=np.array(starts, dtype=np.float64),
        window_lengths=np.array(lengths, dtype=np.float64),
        window_strip=np.array(strip, dtype=np.int64),
        code_rows=tuple(i for i, k in enumerate(kinds) if k == "code"),
        tips=tips,
    )


def _tip_zone(
    lo: float, hi: float, px: float, stretch: Callable[[float, float], tuple[float, float] | None]
) -> Strips | None:
    """One tip zone ``lo <= t < hi``: strips one pixel wide over the stretch where it is all in the frame."""
    zone = stretch(lo, hi)
    if zone is None:
        return None
    starts = np.arange(lo, hi - 1e-9, px)
    ends = np.append(starts[1:], hi)  # each strip ends where the next starts: no overlap by rounding
    bins = math.ceil((zone[1] - zone[0]) * TIP_BINS_PER_PERIOD)
    rows = [[a, b, zone[0], TIP_BINS_PER_PERIOD, bins] for a, b in zip(starts, ends, strict=True)]
    return Strips(np.array(rows))
