"""The ruler's coarse stage: which way the graduations run, their period, and where the pattern lies.

On the image reduced 4 times: the strongest peak of the windowed spectrum gives the grating's
frequency (direction and period, to about 1 %). Demodulated at that frequency, the image's
coherent modulation across the ruler shows the two parts of the graduation lines and the code
track between them; matching it with the design's layout (the parts differ in length) gives the
ruler's axis and which way it runs. Refusals here: no grating (``off_ruler``), a grating that is
not this ruler's pattern or runs out of the frame across the ruler (``off_ruler``, with the way to
move), too short a stretch in view (``too_few_graduations``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._ruler_errors import OffRulerError, TooFewGraduationsError
from station.vision._ruler_frame import RulerFrame
from station.vision._ruler_spec import RulerSpec

FloatArray = npt.NDArray[np.float64]

#: Reduction of the coarse stage's image.
REDUCE = 4
#: A spectral peak this many times the spectrum's median within the searched ring is a grating.
MIN_PEAK_RATIO = 4.0
#: The gradients must share one direction this much (structure tensor's coherence, 0-1).
MIN_COHERENCE = 0.3
#: The matched layout must explain this much of the modulation profile (normalised correlation).
MIN_LAYOUT_MATCH = 0.75


@dataclass(frozen=True)
class CoarseRuler:
    """The coarse stage's result: the frame (periods, +s the ruler's way), period and stretch."""

    frame: RulerFrame
    period_px: float
    stretch: tuple[float, float]
    peak_ratio: float
    layout_match: float


def _grating(small: FloatArray, min_period: float, max_period: float) -> tuple[FloatArray, float, float]:
    """The grating's frequency (cycles per small px, ``(fx, fy)``), its spectral peak ratio and the
    gradients' coherence.

    The direction across the graduations is the gradient structure tensor's main axis (the lines'
    sides and the code cells' edges outweigh their tips, which only add to the other axis); the
    period is the strongest peak of the image projected onto that direction.
    """
    gx = cv2.Scharr(small, cv2.CV_64F, 1, 0)
    gy = cv2.Scharr(small, cv2.CV_64F, 0, 1)
    jxx, jyy, jxy = float((gx * gx).sum()), float((gy * gy).sum()), float((gx * gy).sum())
    spread = jxx + jyy
    coherence = math.hypot(jxx - jyy, 2 * jxy) / spread if spread > 0 else 0.0
    theta = 0.5 * math.atan2(2 * jxy, jxx - jyy)
    normal = np.array([math.cos(theta), math.sin(theta)])
    h, w = small.shape
    s_px = (np.arange(w)[None, :] * normal[0] + np.arange(h)[:, None] * normal[1]).ravel()
    index = np.floor(s_px - s_px.min()).astype(np.int64)
    count = np.bincount(index)
    profile = np.bincount(index, small.ravel()) / np.maximum(count, 1)
    valid = count > 0
    profile = np.where(valid, profile - profile[valid].mean(), 0.0) * np.hanning(len(profile))
    size = 1 << max(12, math.ceil(math.log2(len(profile))) + 3)
    spectrum = np.abs(np.fft.rfft(profile, size))
    freq = np.fft.rfftfreq(size)
    ring = (freq >= 1.0 / max_period) & (freq <= 1.0 / min_period)
    if not ring.any():
        raise OffRulerError(
            f"the image ({w * REDUCE}x{h * REDUCE} px) is too small to show the ruler's graduations"
        )
    masked = np.where(ring, spectrum, 0.0)
    k = int(np.argmax(masked))
    ratio = float(masked[k] / max(float(np.median(spectrum[ring])), 1e-9))
    a, b, c = (math.log(max(float(v), 1e-12)) for v in spectrum[k - 1 : k + 2])
    d = a - 2 * b + c
    peak = (k + (0.5 * (a - c) / d if d < 0 else 0.0)) / size
    return normal * peak, ratio, coherence


def _refined_period(
    small: FloatArray,
    xs: FloatArray,
    ys: FloatArray,
    normal: FloatArray,
    across: FloatArray,
    axis: float,
    sign: int,
    period: float,
    spec: RulerSpec,
) -> float:
    """The period again, from the graduation lines alone (the code track's cells, seen with them,
    pull the whole image's spectral peak by up to a percent): the reduced image's pixels on the
    lines, projected along the ruler in quarter-pixel bins, and the profile's spectral peak."""
    scale = period / spec.pitch_mm
    t_px = sign * (across[0] * xs + across[1] * ys - axis)
    on_lines = np.zeros(np.broadcast_shapes(xs.shape, ys.shape), dtype=bool)
    for lo, hi in spec.line_segments_mm:
        on_lines |= (t_px > lo * scale + 2 * REDUCE) & (t_px < hi * scale - 2 * REDUCE)
    s_px = ((normal[0] * xs + normal[1] * ys) / REDUCE)[on_lines]  # small px
    if len(s_px) < 100:
        return period
    step = 0.25
    index = np.floor((s_px - s_px.min()) / step).astype(np.int64)
    count = np.bincount(index)
    values = np.bincount(index, small[on_lines]) / np.maximum(count, 1)
    seen = count > 0
    profile = np.where(seen, values - values[seen].mean(), 0.0) * np.hanning(len(values))
    size = 1 << max(14, math.ceil(math.log2(len(profile))) + 3)
    spectrum = np.abs(np.fft.rfft(profile, size))
    freq = np.fft.rfftfreq(size, d=step)  # cycles per small px
    expected = REDUCE / period
    near = (freq > 0.8 * expected) & (freq < 1.25 * expected)
    if not near.any():
        return period
    k = int(np.flatnonzero(near)[np.argmax(spectrum[near])])
    a, b, c = (math.log(max(float(v), 1e-12)) for v in spectrum[k - 1 : k + 2])
    d = a - 2 * b + c
    peak = (k + (0.5 * (a - c) / d if d < 0 else 0.0)) * (freq[1] - freq[0])
    return REDUCE / peak if peak > 0 else period


def _overlap_correlation(
    profile: FloatArray, valid: npt.NDArray[np.bool_], pattern: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Pearson correlation of ``pattern`` with ``profile`` at every lag (``np.correlate``'s 'full'
    order), over the bins they share where the profile is ``valid`` (-1 where they share less than
    60 % of the pattern: a pattern partly beyond the frame still matches what is in it), and the
    fraction of the pattern shared."""
    v = valid.astype(np.float64)
    x = profile * v

    def corr(a: FloatArray, b: FloatArray) -> FloatArray:
        return np.asarray(np.correlate(a, b, mode="full"))

    ones = np.ones_like(pattern)
    n = corr(v, ones)
    sx, sxx = corr(x, ones), corr(x * profile, ones)
    sy, syy, sxy = corr(v, pattern), corr(v, pattern * pattern), corr(x, pattern)
    safe = np.maximum(n, 1.0)
    cov = sxy - sx * sy / safe
    var = np.maximum(sxx - sx * sx / safe, 0.0) * np.maximum(syy - sy * sy / safe, 0.0)
    enough = (n >= 0.6 * len(pattern)) & (var > 1e-12)
    return np.where(enough, cov / np.sqrt(np.where(enough, var, 1.0)), -1.0), n / len(pattern)


def _layout(spec: RulerSpec, period_px: float, step: float) -> tuple[FloatArray, float]:
    """The expected coherent modulation across the ruler (1 on the lines, 0 elsewhere) on a grid of
    ``step`` px from the axis, and the grid's first offset (px)."""
    scale = period_px / spec.pitch_mm
    half = spec.line_length_mm / 2 * scale
    grid = np.arange(-half - 4 * step, half + 4 * step + step / 2, step)
    pattern = np.zeros(len(grid))
    for lo, hi in spec.line_segments_mm:
        pattern[(grid >= lo * scale) & (grid <= hi * scale)] = 1.0
    return pattern, float(grid[0])


def coarse_ruler(gray: npt.NDArray[np.uint8], spec: RulerSpec, *, min_periods: float) -> CoarseRuler:
    """Find the ruler's grating, axis and direction in ``gray`` (module docstring).

    Raises
    ------
    OffRulerError, TooFewGraduationsError
    """
    h, w = gray.shape
    small = cv2.resize(gray, (w // REDUCE, h // REDUCE), interpolation=cv2.INTER_AREA).astype(np.float64)
    sh, sw = small.shape
    f_small, ratio, coherence = _grating(small, 12.0 / REDUCE, max(min(h, w) / 4.0, 16.0) / REDUCE)
    if ratio < MIN_PEAK_RATIO or coherence < MIN_COHERENCE:
        raise OffRulerError(
            "no ruler graduations in view (no periodic pattern stands out of the image's spectrum): "
            "bring the ruler's graduated band into the frame, in focus"
        )
    f = f_small / REDUCE
    period = 1.0 / float(np.hypot(*f))
    normal = f * period
    across = np.array([-normal[1], normal[0]])
    # coherent modulation across the ruler, on the reduced image (pixel centres in full-size px)
    xs = (np.arange(sw) * REDUCE + (REDUCE - 1) / 2.0)[None, :]
    ys = (np.arange(sh) * REDUCE + (REDUCE - 1) / 2.0)[:, None]
    phase = np.exp(-2j * np.pi * f[0] * xs) * np.exp(-2j * np.pi * f[1] * ys)  # separable: 280 exps
    t_px = across[0] * xs + across[1] * ys
    step = float(REDUCE)
    t_min = float(t_px.min())
    index = np.floor((t_px - t_min) / step).astype(np.int64).ravel()
    bins = int(index.max()) + 1
    count = np.bincount(index, minlength=bins)
    mean = np.bincount(index, small.ravel(), minlength=bins) / np.maximum(count, 1)
    carrier = phase.ravel()
    z = np.bincount(index, (small.ravel() * carrier).real, minlength=bins) + 1j * np.bincount(
        index, (small.ravel() * carrier).imag, minlength=bins
    )
    z -= mean * (
        np.bincount(index, carrier.real, minlength=bins)
        + 1j * np.bincount(index, carrier.imag, minlength=bins)
    )
    total = z.sum()
    profile = np.where(
        count > 0, (z * np.conj(total)).real / max(abs(total), 1e-12) / np.maximum(count, 1), 0.0
    )
    top = float(np.percentile(profile[count > 0], 95))
    if top <= 0:
        raise OffRulerError(
            "no coherent graduations in view: bring the ruler's graduated band into the frame"
        )
    profile /= top
    pattern, first = _layout(spec, period, step)
    best = (-2.0, 1, 0.0, -1.0)
    centres = t_min + (np.arange(bins) + 0.5) * step
    for sign in (1, -1):
        pat = pattern if sign == 1 else pattern[::-1]
        start = first if sign == 1 else -first - (len(pattern) - 1) * step
        r, shared = _overlap_correlation(profile, count > 0, pat)
        score = r * np.sqrt(shared)  # the whole pattern in view is the likelier reading
        k = int(np.argmax(score))
        if score[k] > best[0]:
            # pattern element 0 aligned with profile bin (k - len(pat) + 1): axis position in px
            offset = k - len(pat) + 1
            sub = 0.0
            if 0 < k < len(score) - 1:
                a, b, c = score[k - 1], score[k], score[k + 1]
                d = a - 2 * b + c
                sub = 0.5 * (a - c) / d if d < 0 else 0.0
            axis = float(centres[0] + (offset + sub) * step - start)
            best = (float(score[k]), sign, axis, float(r[k]))
    _, sign, axis, match = best
    if match < MIN_LAYOUT_MATCH:
        raise OffRulerError(
            f"a grating of period {period:.1f} px is in view but not the ruler's pattern across it (layout "
            f"match {match:.2f} < {MIN_LAYOUT_MATCH}): is the whole band, lines and code track, in the frame?"
        )
    n_vec, a_vec, t0 = (normal, across, axis) if sign == 1 else (-normal, -across, -axis)
    period = _refined_period(small, xs, ys, normal, across, axis, sign, period, spec)
    matrix = np.array(
        [
            [n_vec[0] / period, n_vec[1] / period, 0.0],
            [a_vec[0] / period, a_vec[1] / period, -t0 / period],
            [0.0, 0.0, 1.0],
        ]
    )
    frame = RulerFrame(matrix)
    half = spec.line_length_mm / 2 / spec.pitch_mm
    margin = 4.0 / period
    stretch = frame.stretch(-half - margin, half + margin, w, h)
    if stretch is None:
        raise OffRulerError(_move_hint(frame, w, h, spec))
    length = stretch[1] - stretch[0]
    if length < min_periods:
        raise TooFewGraduationsError(
            f"the whole pattern across the ruler is in view over {length:.1f} graduation periods only (at "
            f"least {min_periods:g} needed): centre the ruler in the frame, or turn the camera so that the "
            "ruler runs along the frame's long side"
        )
    return CoarseRuler(frame=frame, period_px=period, stretch=stretch, peak_ratio=ratio, layout_match=match)


def _move_hint(frame: RulerFrame, width: int, height: int, spec: RulerSpec) -> str:
    """'the pattern runs out of the frame: move the camera ~X mm toward ...' (image directions)."""
    cx, cy = (width - 1) / 2.0, (height - 1) / 2.0
    _, t_centre = frame.point(cx, cy)
    _, grad_t = frame.gradient(cx, cy)
    mm = -t_centre * spec.pitch_mm
    direction = -grad_t if mm < 0 else grad_t
    angle = math.degrees(math.atan2(direction[1], direction[0]))
    names = ["right", "down-right", "down", "down-left", "left", "up-left", "up", "up-right"]
    name = names[round(angle / 45.0) % 8]
    return (
        f"the ruler's pattern runs out of the frame across the ruler (the frame's centre is {abs(mm):.2f} mm "
        f"from the ruler's axis): move the view about {abs(mm):.2f} mm so that the axis comes {name} toward "
        "the frame's centre"
    )
