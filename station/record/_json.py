"""JSON values for the record: plain types only, canonical hashing, and no edge point arrays.

Everything stored in a JSON column passes through :func:`jsonable` first, so what a caller gets back
from a write equals what a later read returns on every backend:

* numpy scalars and arrays become Python numbers and lists, tuples become lists, keys become strings;
* non-finite floats (NaN, +/-inf) become ``null``: JSON has no spelling for them and PostgreSQL
  refuses the extensions Python writes.

Measurement results are kept small (:func:`strip_point_arrays`): any key whose name ends in ``points``
(``edge_points``, ``inlier_points`` ...) holding a list of more than :data:`MAX_POINTS` items is
dropped, at any depth. The edges are recomputed from the stored image whenever they are needed
(re-analysis); the record keeps lines, centre, corners and diagnostics.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

MAX_POINTS = 16


def jsonable(value: Any) -> Any:
    """``value`` as plain JSON types (see the module notes); raises TypeError for anything else."""
    if isinstance(value, np.generic):  # before float: np.float64 is a float
        return jsonable(value.item())
    if value is None or isinstance(value, bool | str | int):
        return value
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    raise TypeError(f"cannot store a {type(value).__name__} in the record's JSON: {value!r:.80}")


def json_object(value: Any, what: str) -> dict[str, Any]:
    """A JSON object (dict) for column ``what``; a TypeError naming it for anything else."""
    if not isinstance(value, Mapping):
        raise TypeError(f"{what} must be a dict, not {type(value).__name__}")
    result: dict[str, Any] = jsonable(value)
    return result


def canonical(value: Any) -> str:
    """Canonical JSON text: sorted keys, no spaces, plain types (for hashing)."""
    return json.dumps(jsonable(value), sort_keys=True, separators=(",", ":"), allow_nan=False)


def params_hash(params: Mapping[str, Any]) -> str:
    """sha256 (hex) of the canonical JSON of a parameter set."""
    return hashlib.sha256(canonical(params).encode()).hexdigest()


def strip_point_arrays(value: Any) -> Any:
    """``value`` without point arrays longer than :data:`MAX_POINTS` (see the module notes)."""
    if isinstance(value, dict):
        return {
            k: strip_point_arrays(v)
            for k, v in value.items()
            if not (k.lower().endswith("points") and isinstance(v, list) and len(v) > MAX_POINTS)
        }
    if isinstance(value, list):
        return [strip_point_arrays(v) for v in value]
    return value
