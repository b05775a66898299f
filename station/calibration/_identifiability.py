"""Identifiability: what the data can determine, before any fit.

The Jacobian of the weighted residuals (``CalibrationModel.jacobian``) is scaled to unit column norms;
its singular values give the condition number, its near-null right singular vectors the combinations of
parameters the data cannot tell apart.

Two kinds of deficiency are kept apart:

* **structural** (:data:`STRUCTURAL`): what no pose set can identify on this arm with this measurement
  (relative measurements of an artifact whose pose is itself unknown). Each is verified on the data: the
  parameter's column lies in the span of the identified set's columns, and the combination that
  reproduces it is named. These parameters stay at their nominal values; ``d3`` is folded into ``d2``,
  reported as ``d2+d3``.
* **pose-set deficiencies**: what a given data set fails to determine beyond that (too few or too
  similar configurations). Found by the SVD of the remaining columns and named by QR with column
  pivoting [1]_: the pivoted-out parameters are the dropped subset, each written as the combination of
  kept parameters that reproduces it.

References
----------
.. [1] G. H. Golub, C. F. Van Loan, *Matrix Computations*, 4th ed., section 5.4.2 (QR with column
       pivoting for subset selection).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from station.calibration._model import CalibrationModel
from station.calibration._observations import FloatArray

STRUCTURAL: dict[str, str] = {
    "alpha0": (
        "a rotation of the whole arm about the base's x axis: the artifacts' positions and tilts, free in"
        " the fit, rotate with it (the base frame is defined only through the artifacts)"
    ),
    "a0": "a translation of the whole arm along the base's x axis: the artifacts' positions take it up",
    "d1": "a translation of the whole arm along joint 1's axis: trades with the artifacts' height",
    "theta1_offset": (
        "a rotation of the whole arm about joint 1's axis: trades with the artifacts' positions about that"
        " axis (and their yaw, which point measurements do not see)"
    ),
    "d3": (
        "axes 2 and 3 are parallel: d2 and d3 both slide everything after joint 2 along the same"
        " direction, so only d2+d3 is identifiable (fitted as d2, reported as d2+d3; d3 stays nominal)"
    ),
    "d6": "a translation along joint 6's axis, the flange's z: trades with the tool's z",
    "theta6_offset": (
        "a rotation about joint 6's axis, nearly the optical axis: trades with the tool's rotation about"
        " the optical axis (tool_rz)"
    ),
}
"""What no pose set identifies on the A465 with this measurement, with the reason (see the module notes)."""

REPORTED_NAMES: dict[str, str] = {"d2": "d2+d3", "d3": "d2-d3"}
"""How parameters are reported: ``d2`` carries the identifiable sum; ``d3`` stands for the difference."""

STRUCTURAL_RCOND = 1e-6
"""Relative residual below which a structural parameter's column counts as a combination of the others."""


def reported_name(name: str) -> str:
    """The name a parameter is reported under (``d2`` is ``d2+d3``, ``d3`` is ``d2-d3``)."""
    return REPORTED_NAMES.get(name, name)


@dataclass(frozen=True)
class Deficiency:
    """A parameter (or combination) the data cannot determine, and what it trades with.

    ``combination``: ``{other: k}`` with the parameter's effect equal to ``sum(k * other's effect)`` in
    natural units (e.g. ``d1 -> {"artifact0_z": 1.0}``); ``residual``: how far it is from that (the
    column's relative residual; 0 means exactly indistinguishable).
    """

    name: str
    combination: dict[str, float]
    residual: float
    reason: str = ""

    def describe(self) -> str:
        terms = " ".join(f"{k:+.3g} {n}" for n, k in self.combination.items()) or "(no effect on the data)"
        return f"{self.name} ~ {terms}" + (f": {self.reason}" if self.reason else "")


@dataclass(frozen=True)
class IdentifiabilityReport:
    """The identifiability of the model's parameters on a data set (all names are model names).

    Attributes
    ----------
    singular_values
        Of the unit-column-scaled Jacobian of all parameters, descending.
    null_dimension
        How many of them are below ``STRUCTURAL_RCOND`` times the largest.
    structural
        The structural deficiencies, each with the combination the data shows it trades with.
    structural_verified
        Every structural parameter's column is (to ``STRUCTURAL_RCOND``) a combination of the candidates'
        (on a rich set, ``null_dimension`` is then the structural list's length: nothing else is null).
    candidates
        Every parameter not in the structural list (the identified set on a rich data set).
    identified
        The candidates the data determines (after subset selection).
    condition_number
        Of the unit-column-scaled Jacobian of ``identified``.
    deficient
        Candidates with weight in the near-null directions (what this data set fails to determine).
    dropped
        The candidates subset selection removed, each named as a combination of kept parameters.
    """

    parameters: tuple[str, ...]
    singular_values: tuple[float, ...]
    null_dimension: int
    structural: tuple[Deficiency, ...]
    structural_verified: bool
    candidates: tuple[str, ...]
    identified: tuple[str, ...]
    condition_number: float
    deficient: tuple[str, ...]
    dropped: tuple[Deficiency, ...]
    rcond: float

    @property
    def unidentifiable(self) -> list[str]:
        """The structural list, reported names (``d2-d3`` for d3)."""
        return [reported_name(d.name) for d in self.structural]

    def resolved_by(self, richer: IdentifiabilityReport) -> list[str]:
        """What ``richer`` (another data set) determines that this one does not."""
        return [n for n in self.deficient if n not in richer.deficient and n in richer.identified]


def _combinations(
    Js: FloatArray,
    norms: FloatArray,
    units: FloatArray,
    names: Sequence[str],
    targets: Sequence[int],
    basis: Sequence[int],
) -> list[tuple[dict[str, float], float]]:
    """Each target column as a combination of the ``basis`` columns (one least-squares solve for all):
    natural-unit coefficients of the significant terms, and the relative residual."""
    if not targets:
        return []
    T = Js[:, list(targets)]
    if not basis:
        return [({}, float(v)) for v in np.linalg.norm(T, axis=0)]
    A = Js[:, list(basis)]
    coefs, *_ = np.linalg.lstsq(A, T, rcond=None)
    residuals = np.linalg.norm(T - A @ coefs, axis=0)
    out = []
    for c, j in enumerate(targets):
        coef = coefs[:, c]
        terms: dict[str, float] = {}
        for o in np.argsort(-np.abs(coef))[:8]:
            if abs(coef[o]) < 0.05:
                break
            i = basis[o]
            terms[names[i]] = float(coef[o] * norms[j] / norms[i] * units[i] / units[j])
        out.append((terms, float(residuals[c])))
    return out


def analyse_identifiability(
    model: CalibrationModel,
    jacobian: FloatArray,
    *,
    rcond: float = 1e-4,
    structural: Sequence[str] = tuple(STRUCTURAL),
) -> IdentifiabilityReport:
    """Identifiability of ``model``'s parameters from the Jacobian of all of them (internal units).

    Parameters
    ----------
    model
        The model whose :attr:`~CalibrationModel.names` label the columns.
    jacobian
        ``model.jacobian(delta, arrays, sigmas)`` (all columns), usually at nominal.
    rcond
        A direction of the candidates whose singular value is below ``rcond`` times the largest is a
        pose-set deficiency (its parameters are determined more than ``1/rcond`` times worse than the
        best-determined direction).
    structural
        The structural list (names of :data:`STRUCTURAL` by default).
    """
    names = model.names
    norms = np.linalg.norm(jacobian, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    Js = jacobian / safe
    units = model.internal_unit
    s_all = np.linalg.svd(Js, compute_uv=False)
    null_dim = int(np.sum(s_all < STRUCTURAL_RCOND * s_all[0]))
    struct_idx = [model.index[n] for n in structural]
    cand_idx = [i for i in range(model.size) if i not in struct_idx]

    deficiencies = []
    verified = True
    for j, (combo, residual) in zip(
        struct_idx, _combinations(Js, safe, units, names, struct_idx, cand_idx), strict=True
    ):
        verified &= residual < STRUCTURAL_RCOND * 10 or norms[j] == 0
        deficiencies.append(Deficiency(names[j], combo, residual, STRUCTURAL.get(names[j], "")))

    # pose-set deficiencies among the candidates: SVD for the deficient directions, QR for the subset
    Jc = Js[:, cand_idx]
    _, s, Vt = np.linalg.svd(Jc, full_matrices=False)
    strong = s >= rcond * s[0]
    # each parameter's weight in the near-null space (including the exact null space when rows < columns)
    weight = np.sqrt(np.clip(1.0 - np.sum(Vt[strong] ** 2, axis=0), 0.0, 1.0))
    deficient = tuple(names[cand_idx[i]] for i in np.flatnonzero(weight > 0.1))
    _, R, piv = scipy.linalg.qr(Jc, mode="economic", pivoting=True)
    diag = np.abs(np.diag(R))
    rank = int(np.sum(diag > rcond * diag[0]))
    kept = [cand_idx[p] for p in piv[:rank]]
    out_idx = [cand_idx[p] for p in piv[rank:]]
    dropped = [
        Deficiency(names[j], combo, residual)
        for j, (combo, residual) in zip(
            out_idx, _combinations(Js, safe, units, names, out_idx, kept), strict=True
        )
    ]
    identified = tuple(names[i] for i in sorted(kept))
    s_id = np.linalg.svd(Js[:, sorted(kept)], compute_uv=False)
    return IdentifiabilityReport(
        parameters=names,
        singular_values=tuple(float(v) for v in s_all),
        null_dimension=null_dim,
        structural=tuple(deficiencies),
        structural_verified=bool(verified),
        candidates=tuple(names[i] for i in cand_idx),
        identified=identified,
        condition_number=float(s_id[0] / s_id[-1]),
        deficient=deficient,
        dropped=tuple(dropped),
        rcond=rcond,
    )


__all__ = [
    "REPORTED_NAMES",
    "STRUCTURAL",
    "Deficiency",
    "IdentifiabilityReport",
    "analyse_identifiability",
    "reported_name",
]
