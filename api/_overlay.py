"""The live view's picture: a frame as 8-bit colour PNG with its measurement drawn on it (the four edge
lines, the corners and the centre), as the operator page shows it; a frame the measurement refused
shows the refusal written under it, and the response carries it beside the picture
(:func:`measurement_headers`)."""

from __future__ import annotations

import json
import textwrap
from dataclasses import dataclass
from typing import Any

import cv2
import numpy.typing as npt

from station.vision import to_gray8

LINE = (0, 200, 255)
CORNER = (255, 0, 255)
CENTRE = (0, 255, 0)
REFUSED = (80, 80, 255)
MAX_HEADER_CHARS = 500


@dataclass(frozen=True)
class Picture:
    """A live-view PNG and the measurement drawn on it (a ``station measure --json`` object; None: the
    frame was not measured)."""

    png: bytes
    measurement: dict[str, Any] | None = None


def measurement_headers(result: dict[str, Any] | None) -> dict[str, str]:
    """The measurement beside the picture: ``X-Measurement-Ok`` (``true``/``false``), for a refused
    frame ``X-Measurement-Code`` and ``X-Measurement-Error`` (ASCII, at most 500 characters), and its
    numbers in ``X-Measurement`` (:func:`measurement_header`); none when the frame was not measured."""
    if result is None:
        return {}
    if result.get("ok"):
        return {"X-Measurement-Ok": "true", **measurement_header(result)}
    return {
        **measurement_header(result),
        "X-Measurement-Ok": "false",
        "X-Measurement-Code": _ascii(str(result.get("code") or "unknown"))[:MAX_HEADER_CHARS],
        "X-Measurement-Error": _ascii(str(result.get("error") or "not measured"))[:MAX_HEADER_CHARS],
    }


def _ascii(text: str) -> str:
    return "".join(c if 32 <= ord(c) < 127 else "?" for c in text)


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
    elif result is not None:
        _write_refusal(canvas, result)
    ok, buf = cv2.imencode(".png", canvas)
    if not ok:
        raise ValueError("the frame could not be encoded as PNG")
    return bytes(buf)


def _write_refusal(canvas: npt.NDArray[Any], result: dict[str, Any]) -> None:
    """The measurement's refusal written at the bottom of the frame, on a dark band."""
    h, w = canvas.shape[:2]
    text = _ascii(f"not measured ({result.get('code') or 'unknown'}): {result.get('error') or ''}")
    lines = textwrap.wrap(text, max(20, w // 7))[:3]
    band = 16 * len(lines) + 6
    canvas[max(0, h - band) :, :] //= 4
    for k, line in enumerate(lines):
        y = h - band + 16 * (k + 1)
        cv2.putText(canvas, line, (4, y), cv2.FONT_HERSHEY_SIMPLEX, 0.4, REFUSED, 1, cv2.LINE_AA)


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
    if "error" in doc:
        doc["error"] = str(doc["error"])[:MAX_HEADER_CHARS]
    return {MEASUREMENT_HEADER: json.dumps(doc, ensure_ascii=True, allow_nan=False, default=str)}
