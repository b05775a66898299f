"""What the distance sensor beside the camera reads of the calibration target's plane (``sim.target``'s
views): the twin's head model without its serial link, for benchmarks and tests of the calibration maths.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from sim.distance_sensor import HeadModel, beam_hit
from sim.target import TargetPose

__all__ = ["sensor_distance"]


def sensor_distance(
    pose: TargetPose,
    mount: npt.ArrayLike,
    *,
    rng: np.random.Generator,
    head: HeadModel = HeadModel(),  # noqa: B008 - frozen model, immutable
    samples: int = 10,
) -> float:
    """What the distance sensor beside the camera reads of the plane the target lies in, mm (averaged).

    ``mount``: the head's 4x4 pose in the camera frame; the plane is the target's (the table it lies on,
    parallel to it). Each sample is the true distance along the beam plus the head's repeatability noise,
    shown at its resolution, as ``sim.distance_sensor`` answers; ``samples`` of them are averaged.
    """
    plane = np.eye(4)
    plane[:3, :3], plane[:3, 3] = pose.rotation, pose.translation_mm
    hit = beam_hit(np.asarray(mount, dtype=np.float64), plane)
    if hit.distance_mm is None:
        raise ValueError("the sensor's beam does not meet the target's plane")
    noisy = hit.distance_mm + rng.normal(0.0, head.repeatability_mm, samples)
    shown = np.round(noisy / head.resolution_mm) * head.resolution_mm
    return float(np.mean(shown))
