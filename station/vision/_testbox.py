"""Stage 4: TestBox segmentation (seed section 3.2.4, eqs. 5-6, Figure 8).

For a primarily horizontal edge the box scans each column downward from the top. A pixel C is accepted
when (1) its response is > 0 (above the threshold), (2) it is the maximum of column A, the 1 x m column
centred on C with m = 2*TESTHEIGHT + 1 (eq. 5), and (3) columns E and F, of the same height, TESTWIDTH
columns before and after C (n = 2*TESTWIDTH + 1 apart, eq. 6), each hold a non-zero value: this rejects
pixels near the perpendicular groove and its rounded land corners (Figures 7, 9).

Readings of what the seed leaves open (seed-paper.md):
* after a hit the box moves SKIP columns right and ``backoff`` rows back up (the seed: "several"),
  then continues down; a column without a hit sends the box back to the top of the next column;
* columns are visited every SKIP columns whether or not the previous one had a hit;
* column A is cut at the image border (pixels outside count as zero), and E/F outside the image fail.

The other three edges reuse the same scan on a flipped or transposed view (``scan_view``), as the seed
transposes the image for the vertical edges.
"""

from __future__ import annotations

from bisect import bisect_left

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._edges import Edge

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
    w = response.shape[1]
    found = cv2.findNonZero(accept.view(np.uint8))  # (x, y) sorted by row; fast on sparse masks
    xy = np.zeros((0, 2), np.intp) if found is None else found.reshape(-1, 2).astype(np.intp)
    order = np.argsort(xy[:, 0], kind="stable")  # by column, rows still ascending within each
    cols, rows = xy[order, 0], xy[order, 1]
    bounds = np.searchsorted(cols, np.arange(w + 1)).tolist()
    row_list = rows.tolist()
    found_cols: list[int] = []
    found_rows: list[int] = []
    last: int | None = None
    for j in range(0, w, skip):
        lo, hi = bounds[j], bounds[j + 1]
        if lo == hi:
            last = None
            continue
        start = 0 if last is None else max(0, last - backoff)
        k = bisect_left(row_list, start, lo, hi)
        if k == hi:
            last = None
            continue
        last = row_list[k]
        found_cols.append(j)
        found_rows.append(last)
    return np.column_stack([np.asarray(found_cols, np.intp), np.asarray(found_rows, np.intp)]).reshape(-1, 2)


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
