"""The ruler measurement's entry point: image + parameters -> RulerMeasurement (pure: no I/O).

Coarse stage (``_ruler_coarse``), then two passes over the pixels (``_ruler_bins``): the first
fits the graduations' phase from the coarse frame, the second, with the corrected frame, fits it
again and also bins the code track and the line tips. The code names the graduations
(``_ruler_code``), the tips place the axis (``_ruler_tips``), and the result is read at the
reference pixel. The design and the method's reasons: ``station/vision/RULER.md``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from station.vision._image import check_quality, image_bit_depth, to_gray8
from station.vision._ruler_bins import Strips, fold
from station.vision._ruler_coarse import coarse_ruler
from station.vision._ruler_code import cell_darkness, read_code
from station.vision._ruler_correction import FrameCorrection, fit_correction
from station.vision._ruler_errors import OffRulerError, TooFewGraduationsError
from station.vision._ruler_frame import RulerFrame
from station.vision._ruler_layout import Plan, plan
from station.vision._ruler_lens import lens_coordinates
from station.vision._ruler_params import RulerParams
from station.vision._ruler_phase import (
    WindowPhases,
    Windows,
    template_value,
    window_phases,
    windows_from_bins,
)
from station.vision._ruler_result import RulerMeasurement
from station.vision._ruler_spec import RulerSpec
from station.vision._ruler_tips import Tips, contrasts, fit_tip

FloatArray = npt.NDArray[np.float64]

#: Noise floor of the bins' residuals (DN): 8-bit quantisation.
QUANTISATION_DN = 0.3
#: The first pass looks at every second pixel of every second row (the frame it gives is only the
#: second pass's starting point).
FIRST_PASS_STEP = 2
#: A window (at the frame's edge) with fewer pixels than this fraction of the median is left out.
MIN_WINDOW_FILL = 0.25
#: A window whose contrast is below this fraction of the best windows' shows no graduations (an end).
MIN_WINDOW_CONTRAST = 0.3


def measure_ruler(
    image: object, params: RulerParams | None = None, *, significant_bits: int | None = None
) -> RulerMeasurement:
    """Measure where along the ruler the image's reference pixel lies.

    Parameters
    ----------
    image : ndarray
        2-D uint8 or uint16, or BGR/BGRA colour; any size from 64 px (not modified).
    params : RulerParams, optional
        The ruler, the camera model, limits; default the design's ruler, no camera model.
    significant_bits : int, optional
        Significant bits per sample recorded by the file (PNG's sBIT).

    Returns
    -------
    RulerMeasurement
        ``position_mm``, ``offset_mm``, ``angle_deg`` at the reference pixel, the code read, diagnostics.

    Raises
    ------
    MeasurementError
        InvalidImageError, ImageQualityError, OffRulerError, TooFewGraduationsError,
        CodeUnreadableError, CodeInconsistentError: each says what to do.
    """
    p = params if params is not None else RulerParams()
    spec = p.ruler
    bit_depth = image_bit_depth(image, p.bit_depth or significant_bits)
    gray = to_gray8(image, bit_depth=bit_depth)
    check_quality(gray)
    if spec.marks == "bright":  # the method reads dark marks on a bright ground
        gray = np.ascontiguousarray(255 - gray)
    coords, reference = lens_coordinates(p.camera_matrix, p.dist_coeffs, gray.shape)
    coarse = coarse_ruler(gray, spec, min_periods=p.min_periods)
    period = coarse.period_px
    frame = coarse.frame
    first = plan(frame, period, p, gray.shape, full=False)
    quick = fold(gray, frame, first.strips, coords, step=FIRST_PASS_STEP)
    _, phases, correction, _ = _phase_pass(gray, frame, first, quick, p, quick=True)
    pinhole = _pinhole(p, gray.shape)
    frame = _corrected(frame, correction, gray.shape, pinhole)
    second = plan(frame, period, p, gray.shape, full=True)
    bins = fold(gray, frame, second.strips, coords)
    windows_used, phases, correction, w = _phase_pass(gray, frame, second, bins, p)
    final = _corrected(frame, correction, gray.shape, pinhole)
    remap = _remap(correction)
    code_bins = second.rows(bins, second.code_rows)
    dark, bright = _levels(second, phases, code_bins, remap)
    cells, darkness = cell_darkness(
        code_bins,
        remap(code_bins),
        second.row_ids(second.code_rows),
        spec.code.cells_per_pitch,
        dark,
        bright,
    )
    reading = read_code(cells, darkness, spec)
    cut = _past_the_ends(second, reading.graduation, spec) & (phases.info > 0)
    if cut.any():  # windows the ruler's end cuts: their profile is not the grating's, refit without them
        phases = dataclasses.replace(phases, info=np.where(cut, 0.0, phases.info))
        windows_used = _check_reach(w, phases.info > 0, second, p)
        correction = fit_correction(w, phases, perspective=_perspective(p, frame, gray.shape))
        final = _corrected(frame, correction, gray.shape, pinhole)
        remap = _remap(correction)
    lower, upper = second.tips
    if lower is None or upper is None:
        raise OffRulerError(
            "the tips of the graduation lines are not in view on both sides: bring the whole pattern "
            "across the ruler into the frame"
        )
    zones = ((lower, fold(gray, frame, lower, coords)), (upper, fold(gray, frame, upper, coords)))
    tips = _tips(zones, (frame, final), remap, spec.line_length_mm / 2 / spec.pitch_mm, phases, period)
    final = final.sheared(-tips.axis(0.0), -tips.slope)
    s_ref, t_ref = final.point(*reference)
    grad_s, _ = final.gradient(*reference)
    axis_dir = _axis_direction(final, reference)
    u_ref = s_ref - correction.s_centre
    t_old = t_ref + tips.axis(s_ref)
    g = np.array([1.0, u_ref, t_old, -u_ref * u_ref, -u_ref * t_old])
    sigma_periods = math.sqrt(max(float(g @ correction.covariance @ g), 0.0))
    position = (s_ref + reading.graduation) * spec.pitch_mm
    extra = {
        "period_px": round(1.0 / float(np.hypot(*grad_s)), 6),
        "px_per_mm": round(1.0 / float(np.hypot(*grad_s)) / spec.pitch_mm, 6),
        "periods_in_view": round(coarse.stretch[1] - coarse.stretch[0], 3),
        "windows": {
            "used": correction.used,
            "total": len(correction.residual),
            "in_view": windows_used,
            "cut_by_end": int(cut.sum()),
        },
        "phase_rms_px": round(float(np.sqrt(np.mean(correction.residual**2))) * period, 6),
        "noise_dn": round(phases.noise_dn, 4),
        "rejected_bins": phases.rejected,
        "contrast_dn": round(float(np.median(np.abs(phases.dark - phases.bright))), 3),
        "position_u_nm": round(sigma_periods * spec.pitch_mm * 1e6, 3),
        "certificate_u_nm": round(spec.position_u_nm(position), 3),
        "tips": {
            "width_ratio": round(tips.width * spec.pitch_mm / spec.line_length_mm, 6),
            "blur_px": round(tips.blur, 4),
        },
        "perspective": [round(float(v), 9) for v in correction.e[3:]],
        "bit_depth": bit_depth,
    }
    return RulerMeasurement(
        position_mm=position,
        offset_mm=t_ref * spec.pitch_mm,
        angle_deg=math.degrees(math.atan2(axis_dir[1], axis_dir[0])),
        reference_px=reference,
        frame=final,
        code=reading,
        params=p,
        extra=extra,
    )


def _phase_pass(
    gray: npt.NDArray[np.uint8],
    frame: RulerFrame,
    layout: Plan,
    bins: FloatArray,
    p: RulerParams,
    *,
    quick: bool = False,
) -> tuple[int, WindowPhases, FrameCorrection, Windows]:
    """Window phases, the frame's correction and the windows from one pass's phase strips; the count
    of windows in view with graduations."""
    if len(layout.window_starts) < 3:
        raise TooFewGraduationsError(
            f"fewer than 3 phase windows ({p.window_periods} periods each) fit in the view: centre the "
            "ruler in the frame, or turn the camera so that it runs along the frame's long side"
        )
    w = windows_from_bins(
        layout.rows(bins, layout.phase_rows), layout.window_starts, layout.window_lengths, layout.window_strip
    )
    phases = window_phases(w, outlier_sigma=p.outlier_sigma, noise_floor_dn=QUANTISATION_DN, quick=quick)
    contrast = np.where(np.isfinite(phases.dark - phases.bright), np.abs(phases.dark - phases.bright), 0.0)
    top = float(np.percentile(contrast, 90))
    if top < p.min_contrast_dn:
        raise OffRulerError(
            f"the graduations' contrast is {top:.1f} DN (at least {p.min_contrast_dn:g} needed): check "
            "focus, exposure and lighting, and that the ruler is in view"
        )
    pixels = w.moments[:, 0]
    graduated = contrast >= MIN_WINDOW_CONTRAST * top
    # a window beside one without graduations holds the ruler's end: its profile is cut, not shifted
    strip = layout.window_strip
    same_before = np.concatenate([[False], strip[1:] == strip[:-1]])
    same_after = np.concatenate([strip[:-1] == strip[1:], [False]])
    ended = (same_before & ~np.roll(graduated, 1)) | (same_after & ~np.roll(graduated, -1))
    present = graduated & ~ended & (pixels >= MIN_WINDOW_FILL * np.median(pixels))
    count = _check_reach(w, present, layout, p)
    kept = dataclasses.replace(phases, info=np.where(present, phases.info, 0.0))
    return count, kept, fit_correction(w, kept, perspective=_perspective(p, frame, gray.shape)), w


def _check_reach(w: Windows, present: npt.NDArray[np.bool_], layout: Plan, p: RulerParams) -> int:
    """The count of windows kept, once checked that they span ``min_periods`` along the ruler."""
    span = w.moments[present, 1]
    reach = float(span.max() - span.min()) + float(np.median(layout.window_lengths)) if present.any() else 0.0
    if reach < p.min_periods or np.count_nonzero(present) < 3:
        raise TooFewGraduationsError(
            f"graduations are seen over {reach:.1f} periods only (at least {p.min_periods:g} needed): the "
            "end of the ruler? Move the view along the ruler"
        )
    return int(np.count_nonzero(present))


def _perspective(p: RulerParams, frame: RulerFrame, shape: tuple[int, int]) -> float:
    """The prior standard deviation of the correction's perspective terms (``fit_correction``)."""
    focal = p.camera_matrix[0][0] if p.camera_matrix is not None else p.focal_px
    period = 1.0 / float(np.hypot(*frame.gradient(shape[1] / 2.0, shape[0] / 2.0)[0]))
    return math.tan(math.radians(p.max_tilt_deg)) * period / focal


#: How far (periods) past a missing line's edge its blur can still reach a window (3 sigma of 0.08
#: period, 4 px at the design's 50 px period: the hard preset's blur and 1.5 mm of f/4 defocus).
END_BLUR_PERIODS = 0.25


def _past_the_ends(layout: Plan, graduation: int, spec: RulerSpec) -> npt.NDArray[np.bool_]:
    """The phase windows not wholly on the graduations: beyond a ruler's end the grating stops, so a
    window reaching there, where the next line would have been, sees a cut profile, whose phase is not
    the grating's (the code named the graduation at ``s = 0``; lines at whole ``s`` from 0 to
    ``graduation_count - 1``)."""
    reach = 1.0 - spec.line_width_mm / spec.pitch_mm / 2.0 - END_BLUR_PERIODS  # from a missing line
    lowest = -reach - graduation
    highest = spec.graduation_count - 1 + reach - graduation
    starts, lengths = layout.window_starts, layout.window_lengths
    return np.asarray((starts < lowest) | (starts + lengths > highest))


def _pinhole(p: RulerParams, shape: tuple[int, int]) -> FloatArray:
    """The camera matrix of the frame's pixel coordinates: the model's, or the nominal focal length with
    the principal point at the image's centre."""
    if p.camera_matrix is not None:
        return np.asarray(p.camera_matrix, dtype=np.float64)
    cx, cy = (shape[1] - 1) / 2.0, (shape[0] - 1) / 2.0
    return np.array([[p.focal_px, 0.0, cx], [0.0, p.focal_px, cy], [0.0, 0.0, 1.0]])


def _corrected(
    frame: RulerFrame, correction: FrameCorrection, shape: tuple[int, int], pinhole: FloatArray
) -> RulerFrame:
    """The frame corrected, with ``t`` square to ``s`` on the ruler's plane (through ``pinhole``) and
    kept at the pattern's centre in view."""
    moved = frame.corrected(correction.e, correction.s_centre)
    x, y = moved.image_of(correction.s_centre, 0.0)
    if not (0 <= x < shape[1] and 0 <= y < shape[0]):
        x, y = (shape[1] - 1) / 2.0, (shape[0] - 1) / 2.0
    return moved.squared_in_plane(pinhole, x, y)


Remap = Callable[[FloatArray], FloatArray]


def _remap(correction: FrameCorrection) -> Remap:
    """Mean ``s`` of bins, moved into the corrected frame (first order in the correction)."""
    e0, e1, e2, e3, e4 = correction.e

    def apply(bins: FloatArray) -> FloatArray:
        n = bins[:, 0]
        safe = np.maximum(n, 1.0)
        s = np.where(n > 0, bins[:, 2] / safe, np.nan)
        t = bins[:, 3] / safe
        u = s - correction.s_centre
        return np.asarray(s + e0 + e1 * u + e2 * t - u * (e3 * u + e4 * t))

    return apply


def _levels(
    layout: Plan, phases: WindowPhases, code_bins: FloatArray, remap: Remap
) -> tuple[FloatArray, FloatArray]:
    """The graduations' dark and bright levels at each code bin: a line along ``s`` fitted to the
    windows of the two phase strips beside the code track."""
    s_bins = remap(code_bins)
    strips = layout.window_strip
    # the phase strips just below and above the code track: the last of the lower part and the next
    order = sorted(set(strips.tolist()))
    table = layout.strips.table
    code_t = table[list(layout.code_rows), 0].mean() if layout.code_rows else 0.0
    phase_t = {k: table[layout.phase_rows[k], 0] for k in order}
    below = max((k for k in order if phase_t[k] < code_t), default=order[0], key=lambda k: phase_t[k])
    above = min((k for k in order if phase_t[k] > code_t), default=order[-1], key=lambda k: phase_t[k])
    near = np.isin(strips, [below, above]) & (phases.info > 0)
    centres = layout.window_starts + layout.window_lengths / 2
    s = centres[near]
    fill = np.where(np.isfinite(s_bins), s_bins, 0.0)
    if len(s) >= 2 and np.ptp(s) > 0:  # straight lines by least squares (np.polyfit's, in closed form)
        u = s - s.mean()
        spread = float(u @ u)
        levels = []
        for values in (phases.dark[near], phases.bright[near]):
            levels.append(values.mean() + float(u @ (values - values.mean())) / spread * (fill - s.mean()))
        dark, bright = levels
    else:
        dark = np.full(len(s_bins), float(np.median(phases.dark)))
        bright = np.full(len(s_bins), float(np.median(phases.bright)))
    return np.asarray(dark), np.asarray(bright)


def _tips(
    zones: tuple[tuple[Strips, FloatArray], tuple[Strips, FloatArray]],
    frames: tuple[RulerFrame, RulerFrame],
    remap: Remap,
    half: float,
    phases: WindowPhases,
    period: float,
) -> Tips:
    """The tips' lines in the final frame (``frames[1]``) from the tip zones' bins (``zones``,
    binned in ``frames[0]``); each zone split in two halves along the ruler (``half``: the
    design's tip, periods)."""
    binned, final = frames
    points: dict[tuple[bool, int], tuple[float, float]] = {}
    blurs: list[float] = []
    for (strips, zone), upper in ((zones[0], False), (zones[1], True)):
        rows = len(strips.table)
        strip = np.repeat(np.arange(rows), strips.table[:, 4].astype(np.int64))
        s_zone = remap(zone)
        finite = np.isfinite(s_zone)
        lo, hi = float(np.min(s_zone[finite])), float(np.max(s_zone[finite]))
        cut = lo + np.floor((hi - lo) / 2.0)  # whole periods in the first half
        profile, _ = template_value(phases.template, np.where(finite, s_zone, 0.0))
        for side in (0, 1):
            inside = finite & ((s_zone < cut) if side == 0 else (s_zone >= cut))
            m, t = contrasts(zone[inside], strip[inside], rows, profile[inside], phases.noise_dn)
            t_e, blur = fit_tip(t, m, half if upper else -half, 1.5 / period, inside_below=upper)
            blurs.append(blur)
            raw_s = float(zone[inside, 2].sum()) / max(float(zone[inside, 0].sum()), 1.0)
            points[(upper, side)] = final.point(*binned.image_of(raw_s, t_e))
    return Tips(
        lower=(points[(False, 0)][1], points[(False, 1)][1]),
        upper=(points[(True, 0)][1], points[(True, 1)][1]),
        s_left=0.5 * (points[(False, 0)][0] + points[(True, 0)][0]),
        s_right=0.5 * (points[(False, 1)][0] + points[(True, 1)][0]),
        blur=float(np.mean(blurs)) * period,
    )


def _axis_direction(frame: RulerFrame, reference: tuple[float, float]) -> FloatArray:
    """Unit image direction of the ruler's axis (``t = 0``) toward +s."""
    b = frame.matrix[1]
    direction = np.array([b[1], -b[0]])
    s0, _ = frame.point(*frame.image_of(0.0, 0.0))
    x1, y1 = frame.image_of(s0 + 1.0, 0.0)
    x0, y0 = frame.image_of(s0, 0.0)
    if direction @ np.array([x1 - x0, y1 - y0]) < 0:
        direction = -direction
    del reference
    return np.asarray(direction / np.hypot(*direction))
