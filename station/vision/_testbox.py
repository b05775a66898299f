"""Stage 4: TestBox segmentation (seed section 3.2.4, eqs. 5-6, Figure 8).

For a primarily horizontal edge the box scans each column downward from the top. A pixel C is accepted
when (1) its response is > 0 (above the threshold), (2) it is the maximum of column A, the 1 x m column
centred on C with m = 2*TESTHEIGHT + 1 (eq. 5), and (3) columns E and F, of the same height, TESTWIDTH
columns before and after C (n = 2*TESTWIDTH + 1 apart, eq. 6), each hold a non-zero value: this rejects
pixels near the perpendicular groove and its rounded land corners (Figures 7, 9).

Readings of what the seed leaves open (the seed paper: see README):
* after a hit the box moves SKIP columns right and ``backoff`` rows back up (the seed: "several"),
  then continues down; a column without a hit sends the box back to the top of the next column;
* columns are visited every SKIP columns whether or not the previous one had a hit;
* column A is cut at the image border (pixels outside count as zero), and E/F outside the image fail.

The other three edges reuse the same scan on a flipped or transposed view (``scan_view``), as the seed
transposes the image for the vertical edges.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._edges import Edge
from station.vision._kernels import compiled

Float32Image = npt.NDArray[np.float32]


def acceptance_mask(response: Float32Image, *, testheight: int, testwidth: int) -> npt.NDArray[np.bool_]:
    """Pixels meeting all three TestBox rules, for a downward scan (rows) along columns.

    Vectorised: rule 2 is a vertical running maximum (``cv2.dilate`` with a m x 1 kernel), rule 3 a
    vertical running "any" shifted by +/-TESTWIDTH columns.
    """
    h, w = response.shape
    m = 2 * testheight + 1
    kernel = np.ones((m, 1), np.uint8)
    positive = response > 0
    column_max = cv2.dilate(response, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    is_max = positive & (response >= column_max)
    any_nonzero = cv2.dilate(positive.view(np.uint8), kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    side = np.zeros((h, w), dtype=bool)
    if w > 2 * testwidth:
        side[:, testwidth : w - testwidth] = (any_nonzero[:, : w - 2 * testwidth] > 0) & (
            any_nonzero[:, 2 * testwidth :] > 0
        )
    return is_max & side


def testbox_scan(
    response: Float32Image, *, testheight: int, testwidth: int, skip: int, backoff: int
) -> npt.NDArray[np.intp]:
    """Scan ``response`` downward column by column; return accepted pixels as (N, 2) ``(col, row)``.

    At most one pixel per visited column. The per-column loop is over columns only; each column's
    candidate rows come from one vectorised ``acceptance_mask``.
    """
    accept = acceptance_mask(response, testheight=testheight, testwidth=testwidth)
    h, w = response.shape
    found = cv2.findNonZero(accept.view(np.uint8))  # (x, y); fast on sparse masks
    xy = np.zeros((0, 2), np.intp) if found is None else found.reshape(-1, 2).astype(np.intp)
    return scan_columns(xy[:, 0], xy[:, 1], (h, w), skip=skip, backoff=backoff)


def scan_columns(
    cols: npt.NDArray[np.intp],
    rows: npt.NDArray[np.intp],
    shape: tuple[int, int],
    *,
    skip: int,
    backoff: int,
) -> npt.NDArray[np.intp]:
    """The TestBox's walk over the accepted pixels ``(cols, rows)`` of a (h, w) view: (N, 2) ``(col, row)``.

    Columns 0, SKIP, 2 SKIP ... are visited in turn; in each the box takes the first accepted pixel at
    or below ``start``: row 0 after a column without a hit, else the previous hit's row minus
    ``backoff``. Each column's start depends only on the previous column's hit, so the walk is found
    as a fixed point, all columns at once: after k rounds the first k columns of every run of hits
    are final, and a round that changes no start has reproduced the sequential walk exactly
    (usually after 2-4 rounds).
    """
    h, w = shape
    visited = (cols % skip) == 0
    key = np.sort(cols[visited] * h + rows[visited])  # by column, then row
    col0 = np.arange(0, w, skip, dtype=np.intp) * h
    per_column = np.bincount(key // (h * skip), minlength=col0.size)
    first = np.cumsum(per_column) - per_column  # each column's first accepted pixel, if any
    end = first + per_column
    start = np.zeros(col0.size, np.intp)
    last_key = max(key.size - 1, 0)
    idx = first  # with every start at row 0
    while True:
        hit = idx < end
        row = np.where(hit, key[np.minimum(idx, last_key)] - col0, -1) if key.size else np.full(col0.size, -1)
        following = np.zeros(col0.size, np.intp)
        following[1:] = np.where(hit[:-1], np.maximum(row[:-1] - backoff, 0), 0)
        if np.array_equal(following, start):
            break
        start = following
        idx = np.searchsorted(key, col0 + start)
    found = np.flatnonzero(hit)
    return np.column_stack([found * skip, row[found]]).astype(np.intp).reshape(-1, 2)


def scan_view(response: Float32Image, edge: Edge) -> Float32Image:
    """The view of ``response`` in which ``edge`` is scanned downward (top edge: as is; bottom: rows
    flipped, scanned from the bottom up; left: transposed; right: transposed and flipped)."""
    if edge == "top":
        view = response
    elif edge == "bottom":
        view = response[::-1, :]
    elif edge == "left":
        view = response.T
    else:
        view = response.T[::-1, :]
    return np.ascontiguousarray(view)


def view_to_image(points: npt.NDArray[np.intp], edge: Edge, shape: tuple[int, int]) -> npt.NDArray[np.intp]:
    """Map ``(col, row)`` points of ``scan_view(..., edge)`` back to image ``(x, y)``."""
    h, w = shape
    col, row = points[:, 0], points[:, 1]
    if edge == "top":
        x, y = col, row
    elif edge == "bottom":
        x, y = col, h - 1 - row
    elif edge == "left":
        x, y = row, col
    else:
        x, y = w - 1 - row, col
    return np.column_stack([x, y]).astype(np.intp).reshape(-1, 2)


def segment_edge(
    thresholded: Float32Image, edge: Edge, *, testheight: int, testwidth: int, skip: int, backoff: int
) -> npt.NDArray[np.intp]:
    """TestBox segmentation of one edge on its thresholded response; returns image ``(x, y)`` (N, 2)."""
    view = scan_view(thresholded, edge)
    pts = testbox_scan(view, testheight=testheight, testwidth=testwidth, skip=skip, backoff=backoff)
    h, w = thresholded.shape
    return view_to_image(pts, edge, (h, w))


#: Per edge: (the image axis the scan runs along: 0 = down the rows, 1 = along the columns; scan
#: reversed: from the bottom or from the right).
_SCAN: dict[Edge, tuple[int, bool]] = {
    "top": (0, False),
    "bottom": (0, True),
    "left": (1, False),
    "right": (1, True),
}


def segment_edge_sparse(
    response: Float32Image,
    sign: float,
    edge: Edge,
    level: float,
    candidates: npt.NDArray[np.intp],
    *,
    testheight: int,
    testwidth: int,
    skip: int,
    backoff: int,
) -> npt.NDArray[np.intp]:
    """``segment_edge`` on the pixels above the threshold only: the same points, in the same order.

    ``sign * response`` is the edge's operator response before its negative values are zeroed
    (``directional_responses``: ``top`` is -1 times the downward operator), ``level`` >= 0 the
    threshold (values above it are kept, as ``apply_threshold`` keeps them) and ``candidates`` the
    flat (row-major) indices of the pixels above it. Instead of full-image running maxima
    (``acceptance_mask``), the three rules are checked on each candidate's columns A, E and F
    gathered from the image; pixels below the threshold count as zero as they do in the
    thresholded response. By the compiled kernel when selected (``_kernels``: the same comparisons and
    the section's sequential walk), else numpy (the reference).
    """
    h, w = response.shape
    axis, reverse = _SCAN[edge]
    ck = compiled()
    if ck is not None:
        n_along = w if axis == 0 else h
        out = np.empty(((n_along + skip - 1) // skip, 2), np.int64)
        count = ck.testbox(
            np.ascontiguousarray(response, np.float32),
            float(sign),
            axis,
            reverse,
            float(level),
            np.ascontiguousarray(candidates, np.int64),
            testheight,
            testwidth,
            skip,
            backoff,
            out,
        )
        return out[:count].astype(np.intp, copy=False)
    # scan geometry: "across" runs along the scan (column A's direction), "along" from column to column
    n_across, n_along = (h, w) if axis == 0 else (w, h)
    s_across, s_along = (w, 1) if axis == 0 else (1, w)
    flat = candidates
    y, x = np.divmod(flat, w)
    across, along = (y, x) if axis == 0 else (x, y)
    flat_img = response.ravel()
    value = flat_img[flat]
    offsets = np.arange(-testheight, testheight + 1)
    steps = offsets * s_across

    def window(centre: npt.NDArray[np.intp], pos: npt.NDArray[np.intp]) -> Float32Image:
        """The response over column-A-shaped windows about flat indices ``centre`` (across position
        ``pos``). A window position outside the image repeats the window's centre pixel instead:
        a duplicate changes neither the window's maximum nor whether any value passes the threshold,
        as the zero of the cut-off column does not."""
        # (window position, candidate) layout: the extremes reduce over the first, short axis (fast)
        idx = centre[None, :] + steps[:, None]
        near = (pos < testheight) | (pos >= n_across - testheight)
        if near.any():
            r = np.flatnonzero(near)
            k = pos[None, r] + offsets[:, None]
            idx[:, r] = np.where((k >= 0) & (k < n_across), idx[:, r], centre[None, r])
        return flat_img[idx]

    # in the edge's polarity (sign * response); the thresholded response is that above the level, else 0
    # rule 2: C is the maximum of column A (ties allowed). Values below the threshold are below C's.
    a_win = window(flat, across)
    keep = a_win.max(axis=0) <= value if sign > 0 else a_win.min(axis=0) >= value
    # rule 3: columns E and F, TESTWIDTH before and after C, each hold a value above the threshold
    keep &= (along >= testwidth) & (along < n_along - testwidth)
    if keep.any():
        sel = np.flatnonzero(keep)
        f, a = flat[sel], across[sel]
        for side in (f - testwidth * s_along, f + testwidth * s_along):
            win = window(side, a)
            keep[sel] &= win.max(axis=0) > level if sign > 0 else win.min(axis=0) < -level
    view_col = along[keep]
    view_row = n_across - 1 - across[keep] if reverse else across[keep]
    pts = scan_columns(view_col, view_row, (n_across, n_along), skip=skip, backoff=backoff)
    return view_to_image(pts, edge, (h, w))
