"""A cross is a cross: before a centre is returned, both grooves must continue on both sides of the
crossing, and there must be exactly one crossing in the frame.

Four edges can be fitted, perpendicular and in the right order, to things that are not the artifact's
cross: a T-junction (one arm missing: the edges of the other three arms fit as well as four), or one of
several crossings (two crosses in one frame). Both give a confident number that is wrong. This check
only rejects; it never changes a number.

Every fourth pixel of the image is sampled along each groove (a 4 px step) and across it (the groove
and its lands), by one ``remap`` per groove.

* **Arms** (``incomplete_cross``): where a groove ends is read from its two walls, not from the
  brightness of its middle. At each step, a wall's contrast is the middle of its three land samples
  (the mean of two, or the one, where the others fall outside the frame) minus the middle of its
  three groove samples (at the groove's middle and at 0.15 and 0.3 of its width from it, toward that
  wall), so that one bright speck, glint or chip in the paint, or one dark scratch on the land, on a
  sample changes nothing. A step shows the groove when either wall's contrast reaches 40 % of the
  cross's typical wall contrast (the upper quartile): a groove ends where both its walls end. It is
  the groove when a neighbouring step shows it too (over a stretch: a lone step, e.g. where two
  scratches cross bare land, makes no groove). An arm is present when its farthest groove step lies
  within 10 px (plus the 4 px step) of the farthest step whose wall can be seen in the frame (the
  border, in practice): a groove never ends inside the field of view. Gaps (glints, flecks, specks,
  scratches) in between do not matter, and an arm too short to be seen (a crossing close to the
  border) is present. Issue 19 (finding 5): the previous rule, the lands against the groove's
  *brightest* sample across its width, lost the last few steps to a cluster of chips and specks by
  the border and refused whole crosses ("the right arm ends 280 px from the crossing"); on 240 such
  frames (``hard-specks``, ``tests/vision/test_cross_check.py``) it refused 3 of 480 measurements,
  this rule none, while every T-junction stays refused and an arm that stops 30 px before the border
  is still missing.
* **One crossing** (``multiple_crossings``): every eighth pixel, turned onto the groove's axis and
  averaged along it (a profile across the groove); any dark band
  besides the measured groove, at least half as deep and a third as wide, is a second groove, hence a
  second crossing.

Cost (``python -m bench.cross_check_bench``: the thread's CPU time per 640x480 frame on the loaded
2-core build machine): 0.17-0.28 ms with the compiled kernels, 0.1-0.17 of precise mode's whole
measurement; 0.55-1.2 ms with the numpy reference. Against the rule before, interleaved in one
process on the same frames (of all three presets): compiled 0.17-0.22 ms against 0.16-0.19 ms (the
ratio 0.94-1.33 per round, median 1.08), numpy 0.55-0.65 ms against 0.38-0.42 ms (1.4-1.6). A few
dozen numpy calls, no per-pixel Python loop.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._edges import Edge
from station.vision._errors import MeasurementError
from station.vision._kernels import compiled

FloatArray = npt.NDArray[np.float64]
Line = tuple[float, float, float]

#: The farthest groove step of an arm may stop this short of the farthest visible one (px).
BORDER_TOLERANCE_PX = 10.0
#: A step shows the groove when a wall's contrast reaches this fraction of the cross's typical one.
PRESENT_FRACTION = 0.4
#: Another dark band this deep (fraction of the measured groove's) is a second groove.
SECOND_GROOVE_DEPTH = 0.5
#: Sampling of the image: every ``_REDUCE``-th pixel, which is also the step along an arm (px).
_REDUCE = 4
STEP_PX = float(_REDUCE)
#: The profile across each groove is taken over every ``_COARSE``-th pixel.
_COARSE = 8


class IncompleteCrossError(MeasurementError):
    """One or more arms of the cross end inside the field of view (a T-junction, an L, a stub)."""

    code = "incomplete_cross"


class MultipleCrossingsError(MeasurementError):
    """More than one crossing (more than two grooves) is in the frame."""

    code = "multiple_crossings"


def _direction(line: Line) -> tuple[float, float]:
    """Unit vector along a normal-form line, pointing toward +x (or +y when nearer vertical)."""
    a, b, _ = line
    dx, dy = b, -a
    if abs(dx) >= abs(dy):
        return (dx, dy) if dx > 0 else (-dx, -dy)
    return (dx, dy) if dy > 0 else (-dx, -dy)


def _quantile(values: npt.NDArray[np.floating], q: float) -> float:
    """The ``q`` quantile (nearest rank) by one partition: np.percentile costs ten times more here."""
    k = min(values.size - 1, int(q * values.size))
    return float(np.partition(values, k)[k])


def _span(c: FloatArray, u: FloatArray, shape: tuple[int, int]) -> tuple[int, int]:
    """The steps ``t`` (from, to) for which ``c + t * u`` lies inside the frame, with a step to spare."""
    lo, hi = -math.inf, math.inf
    for ci, ui, size in ((c[0], u[0], shape[1]), (c[1], u[1], shape[0])):
        if abs(ui) > 1e-9:
            a, b = (0.0 - ci) / ui, (size - 1.0 - ci) / ui
            lo, hi = max(lo, min(a, b)), min(hi, max(a, b))
    if not lo <= hi:
        return 0, 1
    return math.floor(lo) - 1, math.ceil(hi) + 2


#: The samples of each wall (``_Groove``'s rows: 0-4 across the groove from -0.3 w to +0.3 w, 5-7 on
#: the land on the + side, 8-10 on the land on the - side): (inside the groove, on the land beyond).
_EDGE_ROWS = (((0, 1, 2), (8, 9, 10)), ((4, 3, 2), (5, 6, 7)))


def _median3(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    """The middle of three values, elementwise (NaN where any is NaN)."""
    return np.asarray(np.maximum(np.minimum(a, b), np.minimum(np.maximum(a, b), c)))


def _middle_seen(samples: FloatArray) -> FloatArray:
    """The middle of each column's seen (not NaN) values among three: the median of three, the mean of
    two, the one; NaN when none is seen."""
    seen = samples == samples
    count = seen.sum(axis=0)
    total = np.where(seen, samples, 0.0).sum(axis=0)
    middle = np.where(count == 2, 0.5 * total, total)
    return np.where(count == 3, _median3(*samples), np.where(count > 0, middle, np.nan))


def _edge_contrast(
    values: npt.NDArray[np.float32], inside: tuple[int, ...], land: tuple[int, ...]
) -> FloatArray:
    """One wall's contrast at each step: the middle of its land samples seen (one needed) minus the
    middle of its three groove samples (all needed, else NaN: not seen), so that one bright speck or
    dark scratch on a sample changes nothing."""
    lands = values[list(land)]
    middle = _median3(*lands).astype(np.float64)  # exact: a median of float32 values is one of them
    partial = np.flatnonzero(np.isnan(middle))  # a land sample outside the frame (near the border)
    if partial.size:
        middle[partial] = _middle_seen(lands[:, partial].astype(np.float64))
    return middle - _median3(*(values[i] for i in inside)).astype(np.float64)


class _Groove:
    """One groove: the contrast of its two walls at each step along it, and the image turned onto its
    axis."""

    def __init__(
        self,
        small: npt.NDArray[np.float32],
        coarse: npt.NDArray[np.float32],
        angle_deg: float,
        centre: FloatArray,
        width_px: float,
    ) -> None:
        sh, sw = small.shape
        a = math.radians(angle_deg)
        u = np.array([math.cos(a), math.sin(a)])  # along the groove
        n = np.array([-math.sin(a), math.cos(a)])  # across it
        c = (centre - _REDUCE // 2) / _REDUCE
        w = width_px / _REDUCE
        gap = max(3.0, 0.15 * width_px) / _REDUCE
        t_from, t_to = _span(c, u, (sh, sw))
        t = np.arange(t_from, t_to, dtype=np.float64)
        ck = compiled()
        if ck is not None:  # the same maps in one pass (``_kernels``)
            mapx, mapy = np.empty((11, t.size), np.float32), np.empty((11, t.size), np.float32)
            ck.groove_maps(
                float(c[0]),
                float(c[1]),
                float(u[0]),
                float(u[1]),
                float(n[0]),
                float(n[1]),
                t_from,
                w,
                gap,
                mapx,
                mapy,
            )
        else:
            land = 0.5 * w + gap + np.array([0.0, 0.15, 0.3]) * w
            s = np.concatenate([np.linspace(-0.3 * w, 0.3 * w, 5), land, -land])
            mapx = (c[0] + t[None, :] * u[0] + s[:, None] * n[0]).astype(np.float32)
            mapy = (c[1] + t[None, :] * u[1] + s[:, None] * n[1]).astype(np.float32)
        values = cv2.remap(
            small, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan
        )
        if ck is not None:  # the same arithmetic in one pass (``_kernels``)
            self.edges = np.empty((2, values.shape[1]))
            ck.edge_contrast(np.ascontiguousarray(values, np.float32), self.edges)
        else:
            samples = np.asarray(values, dtype=np.float32)
            self.edges = np.stack([_edge_contrast(samples, *rows) for rows in _EDGE_ROWS])
        self.distance = t * _REDUCE  # along the groove from the crossing (px)
        # the coarse image turned so that the groove runs along its rows
        ch, cw = coarse.shape
        M = cv2.getRotationMatrix2D(((cw - 1) / 2.0, (ch - 1) / 2.0), angle_deg, 1.0)
        self.turned = cv2.warpAffine(
            coarse, M, (cw, ch), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan
        )
        k = _COARSE // 2
        self.row = float((M @ np.array([(centre[0] - k) / _COARSE, (centre[1] - k) / _COARSE, 1.0]))[1])
        self.width = width_px / _COARSE


def _second_band(g: _Groove) -> float | None:
    """Distance (px) from the measured groove of another dark band parallel to it, if any. By the
    compiled kernel when selected (``_kernels``), else numpy (the reference)."""
    ck = compiled()
    if ck is not None:
        away = ck.second_band(np.ascontiguousarray(g.turned, np.float32), g.row, g.width, SECOND_GROOVE_DEPTH)
        return None if away is None else away * _COARSE
    finite = g.turned == g.turned  # not NaN: inside the frame
    count = finite.sum(axis=1)
    total = np.add.reduce(g.turned, axis=1, where=finite)
    profile = np.where(count >= 0.25 * g.turned.shape[1], total / np.maximum(count, 1), np.nan)
    idx = np.arange(profile.size)
    seen = np.isfinite(profile)
    half = 0.5 * g.width + 1.0
    band = seen & (np.abs(idx - g.row) <= half)
    around = seen & (np.abs(idx - g.row) > 2 * half)
    if not band.any() or around.sum() < 4:
        return None
    baseline = _quantile(profile[around], 0.5)
    depth = baseline - float(profile[band].min())
    if depth <= 0:
        return None
    dark = around & (profile < baseline - SECOND_GROOVE_DEPTH * depth)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], dark.astype(np.int8), [0]])))
    for a, b in zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True):
        if b - a >= max(2.0, g.width / 3.0):
            return abs((a + b - 1) / 2.0 - g.row) * _COARSE
    return None


def check_single_cross(
    gray: npt.NDArray[np.uint8],
    lines: dict[Edge, Line],
    corners: FloatArray,
    widths: tuple[float, float],
) -> None:
    """Raise IncompleteCrossError or MultipleCrossingsError unless the four edges bound one whole cross.

    ``gray``: the 8-bit image; ``lines``: the four edges (normal form, px); ``corners``: the crossing's
    vertices (4, 2) px; ``widths``: (horizontal, vertical) groove widths at the crossing (px).
    """
    centre = corners.mean(axis=0)
    small = gray[_REDUCE // 2 :: _REDUCE, _REDUCE // 2 :: _REDUCE].astype(np.float32)
    coarse = gray[_COARSE // 2 :: _COARSE, _COARSE // 2 :: _COARSE].astype(np.float32)
    h_dir, v_dir = _direction(lines["top"]), _direction(lines["left"])
    # turn the horizontal groove onto the rows; the vertical one onto the rows too (a further 90 deg)
    horizontal = _Groove(small, coarse, math.degrees(math.atan2(h_dir[1], h_dir[0])), centre, widths[0])
    vertical = _Groove(small, coarse, math.degrees(math.atan2(v_dir[1], v_dir[0])), centre, widths[1])
    missing = _missing_arms(horizontal, vertical, widths)
    if missing:
        count = {1: "only three arms", 2: "only two arms", 3: "only one arm", 4: "no arm"}[len(missing)]
        detail = ", ".join(f"the {n} arm ends {d:.0f} px from the crossing" for n, d in missing)
        raise IncompleteCrossError(
            f"{count} of the cross were found: {detail}, inside the field of view (a T-junction, "
            "or not the artifact's crossing); frame the crossing of two whole grooves"
        )
    for g, name in ((horizontal, "horizontal"), (vertical, "vertical")):
        away = _second_band(g)
        if away is not None:
            raise MultipleCrossingsError(
                f"more than one crossing in the frame: a second {name} groove lies {away:.0f} px from "
                "the measured one; frame a single crossing of the artifact"
            )


#: The four arms: name, the groove it lies on (0 horizontal, 1 vertical), its direction along it.
_ARMS = (("right", 0, 1.0), ("left", 0, -1.0), ("lower", 1, 1.0), ("upper", 1, -1.0))


def _missing_arms(
    horizontal: _Groove, vertical: _Groove, widths: tuple[float, float]
) -> list[tuple[str, float]]:
    """The arms that end inside the field of view: (name, distance of the farthest groove step, px).
    By the compiled kernel when selected (``_kernels``), else numpy (the reference)."""
    grooves = (horizontal, vertical)
    ck = compiled()
    if ck is not None:
        ends = np.empty(len(_ARMS))
        bits = ck.arms(
            np.ascontiguousarray(horizontal.edges, np.float64),
            np.ascontiguousarray(horizontal.distance, np.float64),
            np.ascontiguousarray(vertical.edges, np.float64),
            np.ascontiguousarray(vertical.distance, np.float64),
            widths[0],
            widths[1],
            PRESENT_FRACTION,
            BORDER_TOLERANCE_PX + STEP_PX,
            ends,
        )
        return [(name, float(ends[i])) for i, (name, _, _) in enumerate(_ARMS) if bits >> i & 1]
    steps = []
    for name, which, sign in _ARMS:
        g = grooves[which]
        other, width = widths[1 - which], widths[which]
        start = 0.5 * other + max(6.0, 0.25 * width)  # past the perpendicular groove's rounded corners
        t = sign * g.distance
        on_arm = t >= start  # a run of consecutive steps: neighbours in it are neighbours on the arm
        steps.append((name, t[on_arm], g.edges[:, on_arm], start))
    every = np.concatenate([e.ravel() for *_, e, _ in steps])
    every = every[np.isfinite(every)]
    if every.size == 0:
        return []
    threshold = PRESENT_FRACTION * max(_quantile(every, 0.75), 5.0)
    missing = []
    for name, t, edges, start in steps:
        seen = np.isfinite(edges).any(axis=0)
        if not seen.any():
            continue  # too short to be seen: its crossing is at the border
        # either wall (an unseen one, NaN, never shows)
        shows: npt.NDArray[np.bool_] = np.asarray((edges >= threshold).any(axis=0))
        beside = np.zeros_like(shows)
        beside[1:] |= shows[:-1]
        beside[:-1] |= shows[1:]
        groove = shows & beside  # over a stretch: a lone step showing it makes no groove
        farthest = float(t[groove].max()) if groove.any() else start
        if float(t[seen].max()) - farthest > BORDER_TOLERANCE_PX + STEP_PX:
            missing.append((name, farthest))
    return missing
