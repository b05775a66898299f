"""The station's scale calibration: the artifact's true groove width, estimated by a validation session.

The groove width is only known to +0/-0.002 in (up to 6 % of the nominal 0.794 mm), and every length the
station measures scales with it. A validation session estimates it from the micrometer table (the
similarity fit's scale) with its standard uncertainty. Only a validation that succeeded and passed every
``fail`` gate (``results.checks``) writes it, as ``DATA/scale-calibration.json``
``{"groove_width_mm", "u_mm", "session_id", "checks", "version"}``; later sessions and ``station measure
--scale-calibration FILE`` measure with it and record which one they used
(``diagnostics.scale_calibration``, the session's ``params.scale_calibration``).

Nothing is lost: every calibration the station has used is kept in ``DATA/scale-calibration-history/``,
one numbered file per change (a validation's, or a revert's), and :func:`revert` goes back to the
calibration that was current before the current one was written (``station scale-calibration
show|history|revert``, and the service's ``/api/v1/station/scale-calibration`` routes).

A calibration session with the cell's rulers (issue 22) gives the width too, without a validation: the
grooves' widths its crossings measured (px) over the magnification the rulers' certified pitch gave
(px/mm). Only such a session that succeeded and passed every ``fail`` gate (the magnification's
agreement with the groove widths among them) writes it, with ``"source": "ruler"`` in the file and
``"action": "ruler"`` in its history entry; a validation's has no ``source`` (its action says it).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import tempfile
from collections.abc import Iterator, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from station._pydantic import problems as describe

FILE_NAME = "scale-calibration.json"
HISTORY_DIR = "scale-calibration-history"
LOCK_NAME = ".scale-calibration.lock"


class ScaleCalibrationError(ValueError):
    """A scale calibration file is missing, unreadable or invalid (the message names the file)."""


class ScaleCalibration(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    groove_width_mm: float = Field(gt=0.05, lt=50.0)
    u_mm: float = Field(ge=0.0, lt=50.0)
    session_id: str | None = None
    checks: list[dict[str, Any]] | None = Field(
        None, description="the gates the validation that wrote it passed (results.checks)"
    )
    version: int | None = Field(None, ge=1, description="its number in the station's history")
    source: Literal["ruler"] | None = Field(
        None, description="'ruler': a calibration session's, from its rulers; absent: a validation's"
    )

    def record(self, source: str | Path | None = None) -> dict[str, Any]:
        """What a measurement records under ``diagnostics.scale_calibration`` (without the checks)."""
        out: dict[str, Any] = self.model_dump(exclude={"checks", "version", "source"})
        if self.source is not None:
            out["source"] = self.source
        if self.version is not None:
            out["version"] = self.version
        if source is not None:
            out["file"] = str(source)
        return out


def load(path: str | Path) -> ScaleCalibration:
    p = Path(path)
    try:
        raw = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise ScaleCalibrationError(f"{p}: no such scale calibration file") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise ScaleCalibrationError(f"{p}: cannot read the scale calibration: {exc}") from exc
    except json.JSONDecodeError as exc:
        raise ScaleCalibrationError(f"{p}: not JSON: {exc}") from exc
    try:
        cal = ScaleCalibration.model_validate(raw)
    except ValidationError as exc:
        problems = describe(exc, "file")
        raise ScaleCalibrationError(f"{p}: not a scale calibration: {problems}") from exc
    if not (math.isfinite(cal.groove_width_mm) and math.isfinite(cal.u_mm)):
        raise ScaleCalibrationError(f"{p}: groove_width_mm and u_mm must be finite")
    return cal


def save(cal: ScaleCalibration, path: str | Path) -> Path:
    """Write atomically (temporary file, fsync, rename)."""
    return _write_json(cal.model_dump(exclude_none=True), Path(path))


def _write_json(doc: Mapping[str, Any], p: Path) -> Path:
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".scale-", dir=p.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(doc, f, indent=2)
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def width_unless_set(calibration: ScaleCalibration | None, assignments: Mapping[str, Any]) -> dict[str, Any]:
    """The measurement value a scale calibration gives, ``{"groove_width_mm": ...}``, unless
    ``assignments`` (``--set``, keyed by the parameter model's field names) set the width themselves:
    ``--set`` wins. ``{}`` without a calibration."""
    if calibration is None or "groove_width_mm" in assignments:
        return {}
    return {"groove_width_mm": calibration.groove_width_mm}


def station_file(data_dir: str | Path) -> Path:
    """Where a station keeps its current scale calibration."""
    return Path(data_dir) / FILE_NAME


# ---------------------------------------------------------------------------------------------- history


class HistoryEntry(BaseModel):
    """One change of the station's scale calibration.

    ``action``: ``validation`` (written by session ``calibration.session_id``), ``ruler`` (written by
    calibration session ``calibration.session_id`` from its rulers), ``revert`` (back to
    version ``restores``), or ``found`` (a calibration file that was there before the history began).
    ``calibration`` None: the station had none after this change (nominal groove width). ``previous``:
    the version current before this one (0: none); None when unknown (nothing to revert to).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    version: int = Field(ge=1)
    written_at: str
    action: Literal["validation", "ruler", "revert", "found"]
    calibration: ScaleCalibration | None
    previous: int | None = Field(None, ge=0)
    restores: int | None = Field(None, ge=0)


class NothingToRevertError(ScaleCalibrationError):
    """The history has no earlier scale calibration to go back to."""


def history_dir(data_dir: str | Path) -> Path:
    return Path(data_dir) / HISTORY_DIR


def history(data_dir: str | Path) -> list[HistoryEntry]:
    """Every change of the station's scale calibration, oldest first."""
    folder = history_dir(data_dir)
    if not folder.is_dir():
        return []
    out = []
    for p in sorted(folder.glob("[0-9][0-9][0-9][0-9]*.json")):
        try:
            out.append(HistoryEntry.model_validate_json(p.read_bytes()))
        except (OSError, ValidationError) as exc:
            raise ScaleCalibrationError(f"{p}: not a scale calibration history entry: {exc}") from exc
    return sorted(out, key=lambda e: e.version)


def current(data_dir: str | Path) -> ScaleCalibration | None:
    """The station's scale calibration (``DATA/scale-calibration.json``), None when it has none."""
    path = station_file(data_dir)
    return load(path) if path.exists() else None


@contextlib.contextmanager
def _locked(data_dir: str | Path) -> Iterator[None]:
    """One writer of the history at a time (the service's revert and a session's end, across processes)."""
    folder = Path(data_dir)
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / LOCK_NAME, "a+b") as f:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _append(data_dir: str | Path, entry: HistoryEntry) -> None:
    path = history_dir(data_dir) / f"{entry.version:04d}.json"
    if path.exists():
        raise ScaleCalibrationError(f"{path} exists: the history is never overwritten")
    _write_json(entry.model_dump(mode="json"), path)


def _started(data_dir: str | Path) -> list[HistoryEntry]:
    """The history, begun with the file found in the data directory when there was none."""
    entries = history(data_dir)
    found = current(data_dir)
    if not entries and found is not None:
        first = HistoryEntry(
            version=1, written_at=_now(), action="found", calibration=found.model_copy(update={"version": 1})
        )
        _append(data_dir, first)
        entries = [first]
    return entries


def _make_current(data_dir: str | Path, cal: ScaleCalibration | None) -> None:
    path = station_file(data_dir)
    if cal is None:
        path.unlink(missing_ok=True)  # kept in the history: the station measures with the nominal width
    else:
        save(cal, path)


def write(data_dir: str | Path, cal: ScaleCalibration) -> HistoryEntry:
    """Make ``cal`` the station's scale calibration; the one it replaces stays in the history."""
    with _locked(data_dir):
        entries = _started(data_dir)
        version = entries[-1].version + 1 if entries else 1
        numbered = cal.model_copy(update={"version": version})
        entry = HistoryEntry(
            version=version,
            written_at=_now(),
            action="ruler" if cal.source == "ruler" else "validation",
            calibration=numbered,
            previous=entries[-1].version if entries else 0,
        )
        _append(data_dir, entry)
        _make_current(data_dir, numbered)
        return entry


def revert(data_dir: str | Path) -> HistoryEntry:
    """Go back to the scale calibration that was current before the current one was written (or to none,
    when there was none); NothingToRevertError when the history does not know of an earlier one."""
    with _locked(data_dir):
        entries = _started(data_dir)
        if not entries or entries[-1].previous is None:
            raise NothingToRevertError(
                f"{history_dir(data_dir)} holds no earlier scale calibration to go back to; a validation "
                "that passes its checks writes a new one (station run validation ...)"
            )
        latest = entries[-1]
        target = next((e for e in entries if e.version == latest.previous), None)
        if latest.previous != 0 and target is None:
            raise ScaleCalibrationError(f"version {latest.previous} is missing from {history_dir(data_dir)}")
        version = latest.version + 1
        cal = None
        if target is not None and target.calibration is not None:
            cal = target.calibration.model_copy(update={"version": version})
        entry = HistoryEntry(
            version=version,
            written_at=_now(),
            action="revert",
            calibration=cal,
            previous=None if target is None else target.previous,
            restores=latest.previous,
        )
        _append(data_dir, entry)
        _make_current(data_dir, cal)
        return entry


def from_validation(kind: str, state: str, results: Mapping[str, Any] | None) -> ScaleCalibration | None:
    """The scale calibration a finished session may write: only a validation that estimated it
    (same-direction approach), or a calibration with rulers, that succeeded and passed every ``fail``
    gate; None otherwise."""
    if kind not in ("validation", "calibration") or state != "succeeded" or not results:
        return None
    if not results.get("scale_calibration"):
        return None
    checks = results.get("checks")
    if not isinstance(checks, list) or any(
        c.get("severity") == "fail" and c.get("passed") is not True for c in checks
    ):
        return None
    return ScaleCalibration.model_validate({**results["scale_calibration"], "checks": checks})


def status(data_dir: str | Path) -> dict[str, Any]:
    """The station's scale calibration as ``station scale-calibration show --json`` and ``GET
    /api/v1/station/scale-calibration`` give it: ``{"file", "calibration", "entry"}`` (the current file's
    content and the history entry that made it current; None when there is none)."""
    cal = current(data_dir)
    entries = history(data_dir)
    entry = next((e for e in reversed(entries) if cal is not None and e.version == cal.version), None)
    return {
        "file": str(station_file(data_dir)),
        "calibration": None if cal is None else cal.model_dump(mode="json"),
        "entry": None if entry is None else entry.model_dump(mode="json"),
    }


def history_json(data_dir: str | Path) -> list[dict[str, Any]]:
    """The history, newest first, as JSON objects."""
    return [e.model_dump(mode="json") for e in reversed(history(data_dir))]
