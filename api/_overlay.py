"""The live view's picture: a frame as 8-bit colour PNG with its measurement drawn on it (the four edge
lines, the corners and the centre), as the operator page shows it."""

from __future__ import annotations

import json
from typing import Any

import cv2
import numpy.typing as npt

from station.vision import to_gray8

LINE = (0, 200, 255)
CORNER = (255, 0, 255)
CENTRE = (0, 255, 0)


def overlay_png(image: npt.NDArray[Any], result: dict[str, Any] | None) -> bytes:
    """PNG bytes of ``image`` (grey 8/16-bit or colour), with ``result`` (a ``station measure --json``
    object) drawn when it is given and ``ok``."""
    grey = to_gray8(image)
    canvas = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)
    if result is not None and result.get("ok"):
        h, w = grey.shape[:2]
        for a, b, c in result.get("lines", []):
            pts = _clip_line(float(a), float(b), float(c), w, h)
            if pts is not None:
                cv2.line(canvas, pts[0], pts[1], LINE, 1, cv2.LINE_AA)
        for x, y in result.get("corners_px", []):
            cv2.circle(canvas, (round(x), round(y)), 4, CORNER, 1, cv2.LINE_AA)
        cx, cy = result.get("center_px", [0.0, 0.0])
        cv2.drawMarker(canvas, (round(cx), round(cy)), CENTRE, cv2.MARKER_CROSS, 16, 1, cv2.LINE_AA)
    ok, buf = cv2.imencode(".png", canvas)
    if not ok:
        raise ValueError("the frame could not be encoded as PNG")
    return bytes(buf)


def _clip_line(
    a: float, b: float, c: float, w: int, h: int
) -> tuple[tuple[int, int], tuple[int, int]] | None:
    """Where the line a*x + b*y = c crosses the image's border."""
    pts: list[tuple[float, float]] = []
    if abs(b) > 1e-12:
        for x in (0.0, w - 1.0):
            y = (c - a * x) / b
            if 0 <= y <= h - 1:
                pts.append((x, y))
    if abs(a) > 1e-12:
        for y in (0.0, h - 1.0):
            x = (c - b * y) / a
            if 0 <= x <= w - 1:
                pts.append((x, y))
    if len(pts) < 2:
        return None
    (x0, y0), (x1, y1) = pts[0], pts[-1]
    return (round(x0), round(y0)), (round(x1), round(y1))


MEASUREMENT_HEADER = "X-Measurement"
"""The response header of a live-view picture that carries its measurement's numbers (JSON, ASCII)."""


def measurement_header(result: dict[str, Any] | None) -> dict[str, str]:
    """``{"X-Measurement": JSON}`` with the measurement's ``ok``, ``center_px``, ``center_mm``, ``code``
    and ``error`` (the numbers the page shows under the picture); empty without a measurement."""
    if result is None:
        return {}
    keys = ("ok", "center_px", "center_mm", "code", "error")
    doc = {k: result.get(k) for k in keys if result.get(k) is not None}
    return {MEASUREMENT_HEADER: json.dumps(doc, ensure_ascii=True, allow_nan=False, default=str)}
