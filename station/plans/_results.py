"""What every kind's typed results model shares: the base (results are read back from the record, so
unknown keys are ignored and every model is frozen) and the gates' verdicts (``results.checks``).

A kind's results model (``station/kinds/<kind>/results.py``) types the object its analysis returns: the
API publishes it in its OpenAPI document, the report parses stored results with it. It describes the
results; it never changes them (the record, ``station run --json`` and the API keep the analysis's own
object).
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class ResultsModel(BaseModel):
    """The base of the kinds' results models and their parts."""

    model_config = ConfigDict(extra="ignore", frozen=True)


class Check(ResultsModel):
    """One gate's verdict (``results.checks``): a failed ``fail`` check failed the session."""

    name: str
    passed: bool
    value: float | None = None
    limit: float | tuple[float, float] | None = None
    severity: str = "fail"
    message: str = ""
