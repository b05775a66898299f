"""A sweep over an archive selection: which stored sessions a sweep reads (validations with at least 3
position captures whose images are present), each trial's figures on one session, and a trial's figures
over the whole selection (the seed's Table 1 over every session).

Over a selection, a trial's MeanE is the mean error over every position of every session (each session's
mean weighted by its positions measured), its MaxE the largest error of any session: the numbers Table 1
would show for the selection's positions taken together, ranked as Table 1 ranks them.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from station.batch import AnyParams, FileResult
from station.compute import LocalBackend, MeasureBackend
from station.compute._backend import Cancelled, Frames, OnResult, as_items
from station.imageio import ImageLimits
from station.imagesets import ImageSet
from station.parameter_study import Trial, run_sweep
from station.plans._selection import Source, missing_images
from station.vision import MeasureParams

if TYPE_CHECKING:
    from station.record import CaptureRow, Record, SessionRow

#: The figures of a trial, per session and over the selection (um).
FIGURES = ("mean_um", "max_um", "parallelogram_mean_um", "parallelogram_max_um")
MIN_POSITIONS = 3
#: Frames a selection's trial step measures at most in one call (its sessions taken together): tasks
#: big enough for a pool or a cluster, steps small enough to pause, stop and resume.
GROUP_FRAMES = 256


def sweep_fits(kind: str) -> str | None:
    """Why a sweep cannot read sessions of ``kind`` (None: a validation, it can)."""
    if kind == "validation":
        return None
    return f"it is a {kind} session; a sweep needs validation sessions: leave it out of the selection"


def position_captures(row: SessionRow, record: Record) -> tuple[CaptureRow, ...] | str:
    """A validation's position captures, or why a sweep cannot read them."""
    caps = tuple(c for c in record.captures(row.id) if c.meta.get("role") == "position")
    if len(caps) < MIN_POSITIONS:
        return (
            f"it has {len(caps)} position captures; a sweep needs at least {MIN_POSITIONS}: leave it out "
            "of the selection (or resume it: station run --resume ID)"
        )
    return missing_images(record, caps) or caps


def image_set_of(source: Source, record: Record) -> ImageSet:
    """A source's position images and commanded displacements, as ``station sweep`` reads a set."""
    root = Path(record.data_dir)
    files = tuple(root / c.path for c in source.captures)
    disp = np.array([c.meta["commanded_um"] for c in source.captures], dtype=np.float64)
    return ImageSet(root, files, disp, {}, {"session": source.session.id})


def groups(sources: Sequence[Source], frames: int = GROUP_FRAMES) -> list[tuple[Source, ...]]:
    """Consecutive sessions in groups of at most ``frames`` position frames (a bigger one alone)."""
    out: list[tuple[Source, ...]] = []
    group: list[Source] = []
    size = 0
    for source in sources:
        n = len(source.captures)
        if group and size + n > frames:
            out.append(tuple(group))
            group, size = [], 0
        group.append(source)
        size += n
    if group:
        out.append(tuple(group))
    return out


@dataclass(frozen=True)
class Measured:
    """Frames measured already, served by path as a backend serves them (``validate`` reads a session's
    frames from it after one call measured the frames of every session of a group)."""

    results: dict[str, FileResult]
    name: str = "frames measured already"

    def measure(
        self,
        items: Frames,
        params: AnyParams,
        *,
        limits: ImageLimits | None = None,
        on_result: OnResult | None = None,
        cancelled: Cancelled | None = None,
    ) -> Iterator[FileResult]:
        for item in as_items(items):
            result = self.results[str(item)]
            if on_result is not None:
                on_result(result)
            yield result

    def close(self) -> None:
        return None


def trial_on_group(
    group: Sequence[Source],
    record: Record,
    base: MeasureParams,
    change: dict[str, Any],
    *,
    jobs: int,
    backend: MeasureBackend | None,
    calibration: str,
    cancelled: Cancelled | None = None,
) -> list[dict[str, Any]]:
    """One trial on each session of ``group``: every frame of the group measured in one call on the
    backend (else a local pool of ``jobs``), then each session validated from its own frames; the
    per-session documents (``session``, ``positions``, FIGURES, ``error``), in order."""
    sets = [image_set_of(source, record) for source in group]
    files = [str(f) for image_set in sets for f in image_set.files]
    params = base.with_values(**change)
    with contextlib.ExitStack() as stack:
        if backend is None:
            backend = stack.enter_context(contextlib.closing(LocalBackend(jobs)))
        measured = Measured(
            dict(zip(files, backend.measure(files, params, cancelled=cancelled), strict=True))
        )
    docs = []
    for source, image_set in zip(group, sets, strict=True):
        trial = run_sweep(image_set, base, [change], backend=measured, calibration=calibration)[0]
        docs.append({"session": source.session.id, **trial_figures(trial)})
    return docs


def trial_figures(trial: Trial) -> dict[str, Any]:
    """A trial's error and figures (um, None where it failed) and the positions it compared."""
    out: dict[str, Any] = {"error": trial.error}
    if trial.result is None:
        out.update(dict.fromkeys(FIGURES), positions=0)
        return out
    comp = trial.result.comparison
    out.update(
        mean_um=comp.rigid.mean,
        max_um=comp.rigid.max,
        parallelogram_mean_um=comp.affine.mean,
        parallelogram_max_um=comp.affine.max,
        positions=len(comp.rigid.errors),
    )
    return out


def pooled(number: int, overrides: dict[str, Any], per_session: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """A trial over the selection from its per-session figures (``session``, ``positions``, FIGURES,
    ``error``): MeanE weighted by positions, MaxE the largest; no figures when it failed on any session
    (a trial is ranked on the whole selection or not at all)."""
    doc: dict[str, Any] = {"number": number, "overrides": overrides, "trial": number}
    failed = [s for s in per_session if s["error"] is not None or s["positions"] == 0]
    if failed:
        said = "; ".join(f"{s['session']}: {s['error']}" for s in failed[:3])
        more = f" (and {len(failed) - 3} more)" if len(failed) > 3 else ""
        doc["error"] = f"failed on {len(failed)} of {len(per_session)} sessions: {said}{more}"
        doc.update(dict.fromkeys(FIGURES))
    else:
        weights = np.array([s["positions"] for s in per_session], dtype=np.float64)
        doc["error"] = None
        for fit in ("", "parallelogram_"):
            means = np.array([s[f"{fit}mean_um"] for s in per_session], dtype=np.float64)
            doc[f"{fit}mean_um"] = float(np.dot(weights, means) / weights.sum())
            doc[f"{fit}max_um"] = float(max(s[f"{fit}max_um"] for s in per_session))
    doc["positions"] = int(sum(s["positions"] for s in per_session))
    doc["sessions"] = [dict(s) for s in per_session]
    return doc
