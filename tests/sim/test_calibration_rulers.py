"""The calibration's synthetic ruler frames: rendered by the twin and measured, they read what the twin's
exact truth says (the identification's tests use the exact frames, the bench the rendered ones)."""

from __future__ import annotations

import numpy as np

from sim import calibration_sessions as synthetic
from sim.calibration_rulers import RulerPlan, ruler_session
from sim.cell_rulers import DEFAULT_RULERS

PLAN = RulerPlan(
    positions_mm=(15.0, 205.0),
    turns_deg=(0.0, 90.0),
    max_solutions=1,
    depth_offsets_mm=(1.5,),
    depth_positions_mm=(95.0,),
    lean_azimuths_deg=(0.0, 90.0),
    lean_positions_mm=(125.0,),
)


def test_rendered_and_measured_frames_read_the_twins_truth() -> None:
    truth = synthetic.make_truth(2, rulers=DEFAULT_RULERS, magnification_error=-0.015, sensor_z_error=0.2)
    frames = {1: truth.rulers[1]}  # the table's ruler along +x
    args = (truth.kinematics, truth.camera, truth.mount, frames)
    refused: list[str] = []
    measured = ruler_session(*args, nominal=synthetic.CAMERA, plan=PLAN, seed=5, refused=refused)
    exact = ruler_session(
        *args, nominal=synthetic.CAMERA, plan=PLAN, seed=5, rendered=False, measure_noise_mm=0.0,
        measure_scale_noise=0.0,
    )  # fmt: skip
    assert refused == []
    assert len(measured) == len(exact) == 2 * 2 + 1 + 2
    for m, e in zip(measured, exact, strict=True):
        assert m.joints_deg == e.joints_deg
        assert m.z_mm == e.z_mm
        assert abs(m.position_mm - e.position_mm) < 1e-4  # 0.1 um (the arm's noise is 5 um)
        assert abs(m.offset_mm - e.offset_mm) < 3e-3
        assert m.px_per_mm is not None
        assert e.px_per_mm is not None
        assert abs(m.px_per_mm / e.px_per_mm - 1.0) < 3e-5
    # the scale read is the true camera's at the frames' depth (the pinhole 68 mm from the ruler), not the
    # nominal's
    square = [m.px_per_mm or 0.0 for m in measured[:4]]
    assert np.allclose(square, truth.camera.focal_px / synthetic.CAMERA.working_distance_mm, rtol=2e-4)
    assert not np.allclose(
        square, synthetic.CAMERA.focal_px / synthetic.CAMERA.working_distance_mm, rtol=1e-2
    )
    # the sensor reads the glass where its beam falls on it: along the ruler (turn 0), not across (90)
    assert measured[0].z_mm is not None
    assert measured[1].z_mm is None
