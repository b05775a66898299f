"""The graduations' phase: where the grating is, to a few nanometres, from every graduation in view.

The graduation band is cut into strips across the ruler and each strip into windows about two
periods long. A window's bins (``_ruler_bins``: 256 per window, each pixel at its own ``s``) hold a
super-resolved profile of the graduations there. Each window's phase ``delta`` (how far its
graduations sit from whole values of ``s``) is fitted against one profile shared by all windows
(the template: the window profiles aligned, normalised and made symmetric about a graduation's
centre, so it is the graduations' own blurred shape, every harmonic of it): in each window the
model ``D + D1 u + (A + A1 u) T(s + delta)`` with ``u`` the position in the window, so that a
background and a contrast that vary along the window (illumination, vignetting) do not bias it.
Bins that the model cannot explain (a speck, a scratch, a hot pixel) are dropped. Then one small
projective correction of the frame is fitted to all the windows' phases (``_ruler_correction``).

Fitting the whole profile rather than its fundamental uses the information of the harmonics (the
sharp edges): for the nominal camera the phase's variance is several times lower.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.vision._kernels import compiled

FloatArray = npt.NDArray[np.float64]

#: Bins per phase window (a window is ``window_periods`` to twice that long: some 128 per period).
BINS_PER_WINDOW = 256
#: Samples per period of the tabulated template (cubic interpolation between them).
TEMPLATE_SAMPLES = 4096
#: Fine bins over half a period into which the aligned profiles are averaged before the fit.
FOLD_BINS = 1024
#: Cosine terms of the template (the graduations' profile is even about a graduation's centre), at
#: most, and at least.
HARMONICS = 32
MIN_HARMONICS = 8


@dataclass(frozen=True)
class Windows:
    """The phase windows' bins: ``(windows, bins)`` arrays, and where each window lies.

    ``n``: pixel counts; ``level``: mean grey level; ``s``: mean ``s`` (bin centre when empty);
    ``u``: ``s`` from the window's centre; ``moments``: per window ``(n, mean s, mean t, var s,
    cov s t)``; ``strip``: the strip each window belongs to.
    """

    n: FloatArray
    level: FloatArray
    s: FloatArray
    u: FloatArray
    moments: FloatArray
    strip: npt.NDArray[np.int64]


def windows_from_bins(
    bins: FloatArray, starts: FloatArray, lengths: FloatArray, strip: npt.NDArray[np.int64]
) -> Windows:
    """Group consecutive bins into windows (``BINS_PER_WINDOW`` each) starting at ``starts``, each
    ``lengths`` periods long (the compiled kernel ``_ckernels.ruler_windows`` does the same)."""
    ck = compiled()
    if ck is not None:
        shape = (len(starts), BINS_PER_WINDOW)
        n, level, s, u = (np.empty(shape) for _ in range(4))
        moments = np.empty((len(starts), 5))
        ck.ruler_windows(
            np.ascontiguousarray(bins, dtype=np.float64),
            np.ascontiguousarray(starts, dtype=np.float64),
            np.ascontiguousarray(lengths, dtype=np.float64),
            n,
            level,
            s,
            u,
            moments,
        )
        return Windows(n=n, level=level, s=s, u=u, moments=moments, strip=strip)
    b = bins.reshape(len(starts), BINS_PER_WINDOW, bins.shape[1])
    n = b[..., 0]
    safe = np.maximum(n, 1.0)
    centres = starts[:, None] + (np.arange(BINS_PER_WINDOW) + 0.5) / BINS_PER_WINDOW * lengths[:, None]
    s = np.where(n > 0, b[..., 2] / safe, centres)
    total = n.sum(axis=1)
    ok = np.maximum(total, 1.0)
    mean_s = b[..., 2].sum(axis=1) / ok
    mean_t = b[..., 3].sum(axis=1) / ok
    var_s = b[..., 4].sum(axis=1) / ok - mean_s**2
    cov_st = b[..., 5].sum(axis=1) / ok - mean_s * mean_t
    moments = np.column_stack([total, mean_s, mean_t, var_s, cov_st])
    return Windows(
        n=np.ascontiguousarray(n),
        level=np.ascontiguousarray(b[..., 1] / safe),
        s=np.ascontiguousarray(s),
        u=np.ascontiguousarray(s - (starts + lengths / 2)[:, None]),
        moments=moments,
        strip=strip,
    )


def _solve(weight: FloatArray, columns: list[FloatArray], values: FloatArray) -> FloatArray:
    """Per window, the weighted least-squares coefficients of ``values`` on ``columns``."""
    x = np.stack(columns, axis=1)  # (windows, p, bins)
    xw = x * weight[:, None, :]
    normal = xw @ np.swapaxes(x, 1, 2)
    rhs = (xw @ values[:, :, None])[:, :, 0]
    p = normal.shape[1]
    scale = np.maximum(np.einsum("wii->wi", normal), 1e-300)
    normal = normal + np.eye(p) * (1e-12 * scale[:, :, None])
    return np.asarray(np.linalg.solve(normal, rhs[:, :, None])[:, :, 0])


def template_value(grid: FloatArray, phase: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The periodic template (Catmull-Rom cubic through ``grid``) and its derivative at ``phase``
    (the compiled kernel ``_ckernels.ruler_template`` does the same)."""
    ck = compiled()
    if ck is not None:
        flat = np.ascontiguousarray(phase, dtype=np.float64).ravel()
        value, slope = np.empty(flat.shape), np.empty(flat.shape)
        ck.ruler_template(np.ascontiguousarray(grid, dtype=np.float64), flat, value, slope)
        return value.reshape(np.shape(phase)), slope.reshape(np.shape(phase))
    size = len(grid)
    x = (phase - np.floor(phase)) * size
    i0 = np.floor(x).astype(np.int64)
    f = x - i0
    a, b = grid[i0 % size], grid[(i0 + 1) % size]
    am, bp = grid[(i0 - 1) % size], grid[(i0 + 2) % size]
    c1 = b - am
    c2 = 2 * am - 5 * a + 4 * b - bp
    c3 = 3 * (a - b) + bp - am
    value = a + 0.5 * f * (c1 + f * (c2 + f * c3))
    slope = 0.5 * (c1 + f * (2 * c2 + 3 * f * c3)) * size
    return np.asarray(value), np.asarray(slope)


def _template(w: Windows, weight: FloatArray, coef: FloatArray, delta: FloatArray) -> FloatArray:
    """The windows' profiles aligned by ``delta`` and normalised, as one symmetric profile.

    Each bin's value at its exact phase (folded about a graduation's centre, ``|phase|`` in 0-1/2)
    is first averaged into ``FOLD_BINS`` fine bins (exact mean phase kept), then a cosine series of
    ``HARMONICS`` terms is fitted to them by weighted least squares and tabulated at
    ``TEMPLATE_SAMPLES`` points per period. The series is even, so the template is symmetric about
    the graduation's centre by construction, and it is fitted at the samples' own phases: no
    smoothing and no bias from where the pixels happen to sample the period.
    """
    total, sum_x, sum_v = _folded(w, weight, coef, delta)
    seen = total > 0
    weights = total[seen]
    mean_x = sum_x[seen] / weights
    mean_v = sum_v[seen] / weights
    # normal equations of the cosine series from the moments M_j = sum w cos(2 pi j x), j <= 2K:
    # sum w cos(k a) cos(l a) = (M_|k-l| + M_(k+l)) / 2 (a matrix-vector product, no matrix product)
    harmonics = _resolvable(mean_x)
    moments, rhs = _cosine_sums(mean_x, weights, mean_v, 2 * harmonics, harmonics)
    k = np.arange(harmonics + 1)
    normal_eq = 0.5 * (moments[np.abs(k[:, None] - k[None, :])] + moments[k[:, None] + k[None, :]])
    normal_eq += np.eye(harmonics + 1) * 1e-10 * np.trace(normal_eq) / (harmonics + 1)
    series = np.linalg.solve(normal_eq, rhs)
    # tabulated by an inverse real FFT: grid[j] = sum_k series[k] cos(2 pi k j / TEMPLATE_SAMPLES)
    spectrum = np.zeros(TEMPLATE_SAMPLES // 2 + 1)
    spectrum[: harmonics + 1] = series
    spectrum[1 : harmonics + 1] *= 0.5
    return np.asarray(np.fft.irfft(spectrum, TEMPLATE_SAMPLES) * TEMPLATE_SAMPLES)


def _folded(
    w: Windows, weight: FloatArray, coef: FloatArray, delta: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The windows' bins normalised by each window's background and contrast (``coef``'s first four
    columns) and folded about a graduation's centre into ``FOLD_BINS`` fine bins: per fine bin the
    total weight (``weight`` times the contrast squared), and its sums of the folded phase and of the
    normalised level. The compiled kernel (``_ckernels.ruler_profile``) does the same."""
    ck = compiled()
    if ck is not None:
        out = np.empty((FOLD_BINS, 3))
        ck.ruler_profile(
            w.level,
            w.s,
            w.u,
            np.ascontiguousarray(weight, dtype=np.float64),
            np.ascontiguousarray(coef[:, :4], dtype=np.float64),
            np.ascontiguousarray(delta, dtype=np.float64),
            out,
        )
        return out[:, 0], out[:, 1], out[:, 2]
    contrast = coef[:, 2:3] + coef[:, 3:4] * w.u
    normal = (w.level - coef[:, 0:1] - coef[:, 1:2] * w.u) / np.where(np.abs(contrast) > 1e-9, contrast, 1e-9)
    phase = w.s + delta[:, None]
    phase = np.abs(phase - np.rint(phase))  # 0 at a graduation's centre, 1/2 midway
    # each bin weighed by its information, n contrast^2: a window with no graduations (beyond the
    # ruler's end) has none, and its noise, divided by a contrast near 0, stays out
    informed = weight * np.nan_to_num(contrast) ** 2
    keep = (informed > 0) & np.isfinite(normal)
    x, v, wt = phase[keep], normal[keep], informed[keep]
    index = np.minimum((x * 2 * FOLD_BINS).astype(np.int64), FOLD_BINS - 1)
    sums = [
        np.bincount(index, values, minlength=FOLD_BINS).astype(np.float64) for values in (wt, wt * x, wt * v)
    ]
    return sums[0], sums[1], sums[2]


def _cosine_sums(
    x: FloatArray, weight: FloatArray, value: FloatArray, top: int, harmonics: int
) -> tuple[FloatArray, FloatArray]:
    """``sum weight cos(2 pi j x)`` for ``j = 0 .. top`` and ``sum weight value cos(2 pi k x)`` for
    ``k = 0 .. harmonics`` (the compiled kernel ``_ckernels.ruler_cosines`` does the same)."""
    ck = compiled()
    if ck is not None:
        moments, rhs = np.empty(top + 1), np.empty(harmonics + 1)
        ck.ruler_cosines(
            np.ascontiguousarray(x, dtype=np.float64),
            np.ascontiguousarray(weight, dtype=np.float64),
            np.ascontiguousarray(value, dtype=np.float64),
            moments,
            rhs,
        )
        return moments, rhs
    cosines = _cosines(x, top)
    return np.asarray(cosines @ weight), np.asarray(cosines[: harmonics + 1] @ (weight * value))


def _resolvable(x: FloatArray) -> int:
    """How many cosine terms the folded phases ``x`` (0 to 1/2) can pin down: fewer than
    ``1 / (2 gap)`` for their widest gap. A ruler along the pixel rows with a whole number of pixels
    per period samples the period at that many phases only; elsewhere every harmonic is kept."""
    edges = np.concatenate([[0.0], np.sort(x), [0.5]])
    gap = float(np.max(np.diff(edges)))
    return int(np.clip(math.floor(0.5 / max(gap, 1e-9)) - 1, MIN_HARMONICS, HARMONICS))


def _cosines(x: FloatArray, top: int) -> FloatArray:
    """``cos(2 pi k x)`` for ``k = 0 .. top`` (rows) and each ``x`` (columns), (top + 1, len(x)): real
    parts of the powers of ``exp(2 pi i x)``, each from the last (a row at a time: numpy's cumulative
    product along a short axis costs 5x as much)."""
    z = np.exp(2j * np.pi * np.asarray(x, dtype=np.float64))
    powers = np.empty((top + 1, len(z)), dtype=np.complex128)
    powers[0] = 1.0
    for k in range(1, top + 1):
        np.multiply(powers[k - 1], z, out=powers[k])
    return np.ascontiguousarray(powers.real)


@dataclass(frozen=True)
class WindowPhases:
    """Each window's phase (periods), its information (1 / variance at unit noise), and the fit.

    ``contrast``: the template's coefficient (its scale in grey levels, signed); ``dark``/``bright``:
    the fitted grey levels at a graduation's centre and midway between two, at
    each window's centre (for reading the code); ``noise_dn``: the robust rms of the bins' residuals
    scaled to one pixel; ``rejected``: bins dropped as outliers.
    """

    delta: FloatArray
    info: FloatArray
    amplitude: FloatArray
    contrast: FloatArray
    dark: FloatArray
    bright: FloatArray
    noise_dn: float
    rejected: int
    template: FloatArray


def _round(
    w: Windows, weight: FloatArray, grid: FloatArray, delta: FloatArray, *, residual: bool
) -> tuple[FloatArray, FloatArray | None]:
    """One least-squares round of every window against the profile ``grid`` at phase ``s + delta``.

    Returns ``(coef, residuals)``: per window the coefficients of ``(1, u, T, u T, T')`` and
    ``sum(weight T'^2)`` (``(windows, 6)``), and, when asked, each bin's residual without the ``T'``
    term times ``sqrt(n)``. The compiled kernel (``_ckernels.ruler_fit``) does the same.
    """
    ck = compiled()
    if ck is not None:
        coef = np.empty((len(delta), 6))
        out = np.empty_like(w.n) if residual else None
        ck.ruler_fit(
            w.n,
            w.level,
            w.s,
            w.u,
            np.ascontiguousarray(weight, dtype=np.float64),
            grid,
            np.ascontiguousarray(delta),
            coef,
            out,
        )
        return coef, out
    value, slope = template_value(grid, w.s + delta[:, None])
    columns = [np.ones_like(w.u), w.u, value, w.u * value, slope]
    coef5 = _solve(weight, columns, w.level)
    coef = np.column_stack([coef5, np.sum(weight * slope * slope, axis=1)])
    if not residual:
        return coef, None
    model = coef[:, 0:1] + coef[:, 1:2] * w.u + (coef[:, 2:3] + coef[:, 3:4] * w.u) * value
    return coef, (w.level - model) * np.sqrt(w.n)


#: The fundamental alone, tabulated like a template (``cos``: bright at whole ``s``).
_COSINE = np.cos(2 * np.pi * np.arange(TEMPLATE_SAMPLES) / TEMPLATE_SAMPLES)
_COSINE.setflags(write=False)


def _step(coef: FloatArray) -> FloatArray:
    """The Gauss-Newton step of each window's phase from a round's coefficients (at most 0.1 period)."""
    contrast = np.where(np.abs(coef[:, 2]) > 1e-9, coef[:, 2], 1e-9)
    return np.asarray(np.nan_to_num(np.clip(coef[:, 4] / contrast, -0.1, 0.1)))


def window_phases(
    w: Windows, *, outlier_sigma: float, noise_floor_dn: float, quick: bool = False
) -> WindowPhases:
    """Fit every window's phase against the shared template (module docstring).

    ``quick``: one template and one round against it, no outliers dropped (the first, coarse pass:
    its phases only place the second pass's bins, whose own fit moves them again by some 0.03 px).
    """
    n = w.n
    delta = np.zeros(len(n))
    # the fundamental: dark graduations at whole s + delta
    coef, _ = _round(w, n, _COSINE, delta, residual=False)
    delta = delta + np.nan_to_num(np.arctan2(-2 * np.pi * coef[:, 4], -coef[:, 2]) / (2 * np.pi))
    amp = np.nan_to_num(np.hypot(coef[:, 2], 2 * np.pi * coef[:, 4]))
    centre = np.angle(np.sum(amp**2 * n.sum(axis=1) * np.exp(2j * np.pi * delta))) / (2 * np.pi)
    delta = centre + ((delta - centre + 0.5) % 1.0 - 0.5)
    start = np.column_stack([coef[:, 0], coef[:, 1], -amp, np.zeros_like(amp)])
    grid = _template(w, n, start, delta)
    if quick:  # one round against the template: a second would move the phases by some 1e-4 px
        coef, _ = _round(w, n, grid, delta, residual=False)
        delta = delta + _step(coef)
        return _phases(coef, delta, grid, noise_floor_dn, 0)
    # a round against the first template; a second with the bins' residuals: outliers dropped and
    # the template made again from what is left; one more round against it (a further round moves
    # the windows' phases by some 2e-7 px)
    coef, _ = _round(w, n, grid, delta, residual=False)
    delta = delta + _step(coef)
    coef, residual = _round(w, n, grid, delta, residual=True)
    assert residual is not None
    noise = max(1.4826 * float(np.median(np.abs(residual[n > 0]))), noise_floor_dn)
    weight = n * (np.abs(residual) < outlier_sigma * noise)
    delta = delta + _step(coef)
    grid = _template(w, weight, coef, delta)
    coef, _ = _round(w, weight, grid, delta, residual=False)
    delta = delta + _step(coef)
    return _phases(coef, delta, grid, noise, int(np.count_nonzero((weight == 0) & (n > 0))))


def _phases(
    coef: FloatArray, delta: FloatArray, grid: FloatArray, noise: float, rejected: int
) -> WindowPhases:
    """The windows' phases and what goes with them, from the last round's coefficients."""
    info = coef[:, 2] ** 2 * coef[:, 5]
    info = np.where(np.isfinite(info) & np.isfinite(delta), info, 0.0)
    dark_v, _ = template_value(grid, np.zeros(1))
    bright_v, _ = template_value(grid, np.full(1, 0.5))
    return WindowPhases(
        delta=np.nan_to_num(delta),
        info=info,
        amplitude=np.abs(coef[:, 2]),
        contrast=coef[:, 2],
        dark=coef[:, 0] + coef[:, 2] * float(dark_v[0]),
        bright=coef[:, 0] + coef[:, 2] * float(bright_v[0]),
        noise_dn=noise,
        rejected=rejected,
        template=grid,
    )
