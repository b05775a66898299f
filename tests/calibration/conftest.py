"""One rich synthetic session and its fit, shared by the module's tests (the fit takes about a second)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from station.calibration import CalibrationResult, Observation, identify
from tests.calibration import synthetic

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
