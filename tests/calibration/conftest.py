"""Rich synthetic sessions and their fits, shared by the module's tests (each fit takes a few seconds)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from sim import calibration_sessions as synthetic
from sim.calibration_rulers import ruler_session
from sim.cell_rulers import DEFAULT_RULERS
from station.calibration import CalibrationResult, Observation, RulerObservation, identify

SEED = 3


@dataclass
class Fitted:
    truth: synthetic.Truth
    observations: list[Observation]
    holdout: list[int]
    result: CalibrationResult


@pytest.fixture(scope="package")
def fitted() -> Fitted:
    truth = synthetic.make_truth(SEED)
    observations = synthetic.session(truth, seed=SEED + 1)
    configurations = sorted({o.configuration for o in observations})
    holdout = configurations[1::4]
    result = identify(observations, synthetic.setup_for(), holdout=holdout)
    return Fitted(truth, observations, holdout, result)


@dataclass
class FittedRulers:
    """A session on a cell with rulers, the camera's true scale 1.3 % above its nominal and its sensor
    0.3 mm further along the optical axis than the nominal mount: identified with the ruler frames and,
    for comparison, without them (today's captures, the nominal camera trusted)."""

    truth: synthetic.Truth
    observations: list[Observation]
    rulers: list[RulerObservation]
    holdout: list[int]
    result: CalibrationResult
    without: CalibrationResult


MAGNIFICATION_ERROR = 0.013
SENSOR_Z_ERROR = 0.3


@pytest.fixture(scope="package")
def fitted_rulers() -> FittedRulers:
    truth = synthetic.make_truth(
        SEED, rulers=DEFAULT_RULERS, magnification_error=MAGNIFICATION_ERROR, sensor_z_error=SENSOR_Z_ERROR
    )
    observations = synthetic.session(truth, seed=SEED + 1)
    frames = ruler_session(
        truth.kinematics,
        truth.camera,
        truth.mount,
        truth.rulers,
        nominal=synthetic.CAMERA,
        seed=SEED,
        rendered=False,
    )
    crossing_configs = sorted({o.configuration for o in observations})
    ruler_configs = sorted({o.configuration for o in frames})
    holdout = crossing_configs[1::4] + ruler_configs[1::4]
    setup = synthetic.setup_for(rulers=DEFAULT_RULERS)
    result = identify(observations, setup, rulers=frames, holdout=holdout)
    without = identify(observations, setup, holdout=holdout)
    return FittedRulers(truth, observations, frames, holdout, result, without)
