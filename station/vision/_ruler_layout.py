"""Where the ruler measurement looks: the strips of one pass over the pixels.

Across the ruler (``t``, periods), from the lower tips up: the lower tip zone (strips one pixel
wide), the phase strips of the lines' lower part, the code track's sub-strips, the phase strips of
the upper part, the upper tip zone. Along the ruler each strip covers the stretch over which it is
wholly inside the frame: phase strips in whole windows (``window_periods`` long, centred in the
stretch), the code in bins of 1/16 period, the tip zones in bins of 1/32 period over the stretch
common to their strips.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.vision._ruler_bins import Strips
from station.vision._ruler_frame import RulerFrame
from station.vision._ruler_params import RulerParams
from station.vision._ruler_phase import BINS_PER_PERIOD

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Sub-strips across the code track (a cell's value is their median).
CODE_SUBSTRIPS = 3
CODE_BINS_PER_PERIOD = 16
TIP_BINS_PER_PERIOD = 32
#: Half-width of a tip zone outside the lines (px).
TIP_OUTSIDE_PX = 12.0


@dataclass(frozen=True)
class Plan:
    """The strips of one pass and what each is for (row numbers in ``strips.table``)."""

    strips: Strips
    phase_rows: tuple[int, ...]
    window_starts: FloatArray
    window_strip: IntArray
    window_length: float
    code_rows: tuple[int, ...]
    lower_tip_rows: tuple[int, ...]
    upper_tip_rows: tuple[int, ...]

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

    def stretch(lo: float, hi: float) -> tuple[float, float] | None:
        return frame.stretch(lo, hi, width, height)

    half = spec.line_length_mm / 2 / spec.pitch_mm
    tip_in = margin
    if full:
        lo_t = -half - TIP_OUTSIDE_PX * px
        zone = stretch(lo_t, -half + tip_in)
        if zone is not None:
            edges = np.arange(lo_t, -half + tip_in - 1e-9, px)
            for a in edges:
                b = min(a + px, -half + tip_in)
                rows.append(
                    (a, b, zone[0], TIP_BINS_PER_PERIOD, math.ceil((zone[1] - zone[0]) * 32), "lower")
                )
    parts = [(lo / spec.pitch_mm, hi / spec.pitch_mm) for lo, hi in spec.line_segments_mm]
    code_lo, code_hi = (v / spec.pitch_mm for v in spec.code_track_mm)
    for number, (lo, hi) in enumerate(parts):
        a = lo + (tip_in if number == 0 else margin)
        b = hi - (margin if number == 0 else tip_in)
        if b - a < 2 * px:
            continue
        count = max(1, round((b - a) / (params.strip_px * px)))
        edges = np.linspace(a, b, count + 1)
        for s_lo_t, s_hi_t in itertools.pairwise(edges):
            span = stretch(float(s_lo_t), float(s_hi_t))
            if span is None:
                continue
            windows = int((span[1] - span[0]) // length)
            if windows < 1:
                continue
            start = span[0] + 0.5 * ((span[1] - span[0]) - windows * length)
            bins = windows * round(length * BINS_PER_PERIOD)
            rows.append((float(s_lo_t), float(s_hi_t), start, BINS_PER_PERIOD, bins, "phase"))
        if full and number == 0:
            edges = np.linspace(code_lo + margin, code_hi - margin, CODE_SUBSTRIPS + 1)
            for a2, b2 in itertools.pairwise(edges):
                span = stretch(float(a2), float(b2))
                if span is not None:
                    bins = math.ceil((span[1] - span[0]) * CODE_BINS_PER_PERIOD)
                    rows.append((float(a2), float(b2), span[0], CODE_BINS_PER_PERIOD, bins, "code"))
    if full:
        hi_t = half + TIP_OUTSIDE_PX * px
        zone = stretch(half - tip_in, hi_t)
        if zone is not None:
            edges = np.arange(half - tip_in, hi_t - 1e-9, px)
            for a in edges:
                b = min(a + px, hi_t)
                rows.append(
                    (a, b, zone[0], TIP_BINS_PER_PERIOD, math.ceil((zone[1] - zone[0]) * 32), "upper")
                )
    rows.sort(key=lambda r: r[0])
    table = np.array([r[:5] for r in rows], dtype=np.float64).reshape(-1, 5)
    kinds = [r[5] for r in rows]
    phase = tuple(i for i, k in enumerate(kinds) if k == "phase")
    starts: list[float] = []
    strip: list[int] = []
    per = round(length * BINS_PER_PERIOD)
    for number, i in enumerate(phase):
        count = int(table[i, 4]) // per
        starts += [table[i, 2] + j * length for j in range(count)]
        strip += [number] * count
    return Plan(
        strips=Strips(table) if len(table) else Strips(np.array([[0.0, 1.0, 0.0, 1.0, 1.0]])),
        phase_rows=phase,
        window_starts=np.array(starts, dtype=np.float64),
        window_strip=np.array(strip, dtype=np.int64),
        window_length=length,
        code_rows=tuple(i for i, k in enumerate(kinds) if k == "code"),
        lower_tip_rows=tuple(i for i, k in enumerate(kinds) if k == "lower"),
        upper_tip_rows=tuple(i for i, k in enumerate(kinds) if k == "upper"),
    )
