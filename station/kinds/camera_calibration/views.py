"""The target found in each stored view of a camera calibration, square views followed into the blur.

Tilted views are found by ``detect_target``. The square views of one turn (one ``group``, moved along the
optical axis between them) are found from the one nearest focus (``detect_target``): every other is
followed from it (``follow_target``), the image scale from the sensor's readings (``Z0 / (Z0 + dz)``), and
the one in focus is refined again the same way, so that every square view's corners come from one
refinement window (``FOLLOW_SIGMA_PX``): the fitted distances' bias from the blur then changes smoothly
with the height, where mixing windows would step it. That takes the heights beyond the markers' depth of
field (``TARGET.md``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from station.camcal import (
    CameraCalibrationError,
    SensorReading,
    TargetDetection,
    detect_target,
    follow_target,
)
from station.plans import CaptureResult

__all__ = ["FOLLOW_SIGMA_PX", "FoundViews", "find_views"]

FOLLOW_SIGMA_PX = 4.5
"""The refinement window of the square views (px): measured on noise-free twin frames at f/4 (a blur of
3.1 px/mm), the corners are within 0.003 px on average and 0.035 px rms of the truth up to +/-1.5 mm from
focus with it (a 3 px window: 0.26 px at 1.5 mm, the markers' light reaching it; 6 px: 0.06-0.08 px)."""


@dataclass(frozen=True)
class FoundViews:
    """The views the target was found in, with their readings; ``followed``: which were followed from
    another (out of focus: ``calibrate_intrinsics``'s ``pose_only``); ``missed``: why the others were not."""

    detections: list[TargetDetection]
    readings: list[SensorReading | None]
    missed: list[str]
    followed: list[bool]


def find_views(
    taken: Sequence[CaptureResult],
    load: Callable[[CaptureResult], npt.NDArray[Any]],
    samples: Mapping[int, Sequence[float]],
    working_distance_mm: float,
) -> FoundViews:
    """Find the target in every view of ``taken`` (in order), the square views followed (module docstring).

    ``load`` gives a capture's frame; ``samples`` the sensor's readings by step index (mm).
    """
    reading = {
        c.capture_id: float(np.mean(samples[c.step_index])) if samples.get(c.step_index) else None
        for c in taken
    }
    found: dict[int, TargetDetection] = {}
    missed: dict[int, str] = {}
    square: dict[int, list[CaptureResult]] = {}
    for cap in taken:
        if float(cap.meta.get("tilt_deg", 0.0)) == 0.0 and reading[cap.capture_id] is not None:
            square.setdefault(int(cap.meta["group"]), []).append(cap)
    in_groups = {c.capture_id for views in square.values() for c in views}

    def detect(cap: CaptureResult) -> bool:
        try:
            found[cap.capture_id] = detect_target(load(cap))
        except CameraCalibrationError as exc:
            missed[cap.capture_id] = f"view {cap.meta.get('view')}: {exc}"
            return False
        return True

    for cap in taken:  # the tilted views; a square one is found from its group's reference below
        if cap.capture_id not in in_groups:
            detect(cap)
    followed: set[int] = set()
    for views in square.values():
        # the reference: the view nearest focus the detector finds the target in (nearest first)
        by_height = sorted(views, key=lambda c: abs(float(c.meta.get("height_mm", 0.0))))
        ref = next((c for c in by_height if detect(c)), None)
        if ref is None:
            continue
        z0 = reading[ref.capture_id]
        assert z0 is not None
        reference, reference_image = found[ref.capture_id], load(ref)
        w, h = reference.image_size
        for cap in views:
            z = reading[cap.capture_id]
            assert z is not None
            try:
                found[cap.capture_id] = follow_target(
                    reference_image if cap is ref else load(cap),
                    reference,
                    reference_image,
                    scale=working_distance_mm / (working_distance_mm + (z - z0)),
                    centre_px=((w - 1) / 2.0, (h - 1) / 2.0),
                    sigma_px=FOLLOW_SIGMA_PX,
                )
            except CameraCalibrationError as exc:
                found.pop(cap.capture_id, None)
                missed[cap.capture_id] = f"view {cap.meta.get('view')}: {exc}"
                continue
            missed.pop(cap.capture_id, None)
            if cap.capture_id != ref.capture_id:
                followed.add(cap.capture_id)
    detections = [found[c.capture_id] for c in taken if c.capture_id in found]
    readings = [
        SensorReading(int(c.meta["group"]), r) if (r := reading[c.capture_id]) is not None else None
        for c in taken
        if c.capture_id in found
    ]
    return FoundViews(
        detections,
        readings,
        [missed[c.capture_id] for c in taken if c.capture_id in missed],
        [c.capture_id in followed for c in taken if c.capture_id in found],
    )
