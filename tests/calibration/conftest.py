"""One rich synthetic session and its fit, shared by the module's tests (the fit takes about a second)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from sim import calibration_sessions as synthetic
from station.calibration import CalibrationResult, Observation, identify

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
