"""What fixes a simulated station (:class:`WorldSpec`; frames and signs in ``sim.world``'s docstring)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from sim._render_camera import F4_DEFOCUS_PX_PER_MM
from sim._table import TableImperfections
from sim.arm_errors import FlangeErrors
from sim.artifact import ArtifactSpec, CameraSpec
from sim.cell_rulers import DEFAULT_RULERS, RulerMount
from station.kinematics import DHRow

TableContent = Literal["cross", "ruler", "target"]
"""What can lie on the X-Y table: the crossed artifact, a ruler in its place, or the camera-calibration
target (``World.place_on_table`` swaps it at run time)."""
TABLE_CONTENTS: tuple[TableContent, ...] = ("cross", "ruler", "target")

#: A reference pose of the arm with the camera looking straight down (flange z along -z of the base).
REFERENCE_JOINTS_DEG: tuple[float, ...] = (0.0, 30.0, 60.0, 0.0, 90.0, 0.0)


@dataclass(frozen=True)
class WorldSpec:
    """Everything that fixes a simulated station (see the module docstring for frames and signs)."""

    camera: CameraSpec = field(default_factory=CameraSpec)
    artifact: ArtifactSpec = field(default_factory=ArtifactSpec)
    preset: str = "nominal"
    tool_length_mm: float = 120.0
    reference_joints_deg: tuple[float, ...] = REFERENCE_JOINTS_DEG
    table_rotation_deg: float = 0.3
    artifact_rotation_deg: float = 2.0
    table: TableImperfections = field(default_factory=TableImperfections)
    defocus_px_per_mm: float = F4_DEFOCUS_PX_PER_MM
    """The blur's growth away from the focal plane, px (sigma) per mm: the seed's 1X macro lens at f/4
    (``sim._render_camera.F4_DEFOCUS_PX_PER_MM``; 20 before issue 22, an f/0.6 lens)."""
    flange_errors: FlangeErrors = field(default_factory=FlangeErrors)
    bench_artifacts: tuple[tuple[float, float, float, float, float], ...] = (
        (350.0, 250.0, 380.0, 30.0, 20.0),
        (420.0, -200.0, 340.0, -20.0, -20.0),
        (0.0, -400.0, 400.0, 60.0, -25.0),
        (-100.0, 380.0, 420.0, -45.0, 20.0),
    )
    """Further artifacts fixed on the bench (not on the table), for calibration: each ``(x, y, z, yaw_deg,
    tilt_deg)`` in the base frame: the crossing's position (mm), the turn of its u axis about base z from
    the base's x, and a tilt of the plate about its u axis (an angle block), on blocks above the table's
    plane (the arm's keep-out). The camera sees the artifact nearest its optical axis. The defaults
    spread four around the arm, tilted so that the camera square to them needs the wrist bent sideways
    (joint 4 away from 0 and 180 deg): four joint solutions each within the limits."""
    true_dh: tuple[DHRow, ...] | None = None
    """The arm's true DH table; None: the nominal table plus errors drawn with ``dh_error_seed``."""
    dh_error_seed: int = 0
    artifact_half_size_mm: float = 50.0
    """Half the side of each artifact's top plate (its grooves run across it): the camera sees the
    background beyond it, and the distance sensor twin's beam misses it there (the sensor, 30 mm beside
    the optical axis, reads the plate while the camera looks at the crossing)."""
    background_dn: float = 60.0
    """Grey level of what lies around the artifacts (bench, table top; far out of focus), DN."""
    rulers: tuple[RulerMount, ...] = DEFAULT_RULERS
    """The rulers fixed in the cell (``sim.cell_rulers``): two on the table's plane, one on an angle block,
    on the side of the cell opposite the X-Y table. The camera sees a ruler when its optical axis meets
    the ruler's glass."""
    table_artifact: Literal["cross", "ruler"] = "cross"
    """What the X-Y table carries when the world is built: the crossed artifact, or a ruler in its place
    (``sim._world_rulers``: its middle where the crossing would be, ``s`` along the artifact's u); the
    simulated operator swaps it when a session asks (``World.place_on_table``)."""
    magnification_seed: int | None = None
    """None: the camera's true magnification is its nominal (``camera.px_per_mm``); a seed: the true
    focal length (and so the scale at the focal plane) differs from the nominal by a factor drawn
    uniformly within ``1 +/- magnification_range`` (:func:`magnification_error`), which the station,
    trusting its nominal camera, does not know."""
    magnification_range: float = 0.02
    """Half-width of the seeded magnification error (relative)."""
    calibration_target: bool = False
    """The camera-calibration target on the X-Y table in place of the artifact when the world is built
    (``sim._world_target``); ``World.place_on_table`` swaps it at run time."""
    true_intrinsics_seed: int | None = None
    """None: the target is seen through the true camera's pinhole (:attr:`World.true_camera`); a seed:
    through ``sim.lens.true_intrinsics(seed)`` (focal +/-2 %, principal point +/-20 px, radial
    distortion), which a camera calibration must find. The artifact's renderer stays a pinhole at the
    centre, at the true focal length's scale (the mean of ``fx`` and ``fy``; unless ``magnification_seed``
    is given): one lens, so that a calibrated model agrees with the grooves' scale."""


def magnification_error(seed: int, magnification_range: float = 0.02) -> float:
    """The camera's true magnification over its nominal, minus 1, for ``WorldSpec.magnification_seed``."""
    if not (0.0 <= magnification_range < 0.5):
        raise ValueError(f"magnification_range must be in [0, 0.5), got {magnification_range!r}")
    return float(np.random.default_rng([0x3A6, seed]).uniform(-magnification_range, magnification_range))
