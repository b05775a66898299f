"""The configuration writer: taught values written into ``station.toml`` with its comments and layout
kept (tomlkit), the new file checked before it replaces the old, and the old one backed up.

A write never leaves a half-written or invalid configuration: the new text is validated as a station
configuration (from a temporary file beside it, so that relative paths resolve the same), the old file
is copied to ``station.toml.YYYYMMDD-HHMMSS.bak`` (a number added when that name exists: no backup is
ever overwritten), and the new one replaces it atomically (written, synced, renamed).
"""

from __future__ import annotations

import datetime as _dt
import os
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import tomlkit
from tomlkit.items import Table
from tomlkit.toml_document import TOMLDocument

from station.config import ConfigurationError, StationConfig, load_config

__all__ = ["ConfigUpdate", "set_artifact", "set_reference", "set_sensor_mount_z", "update_config"]


@dataclass(frozen=True)
class ConfigUpdate:
    """What a write did: the file, its backup, what changed (``key: new value`` lines) and the new
    configuration as loaded."""

    path: Path
    backup: Path
    changes: tuple[str, ...]
    config: StationConfig


def _table(doc: TOMLDocument | Table, key: str) -> Any:
    if key not in doc:
        doc[key] = tomlkit.table()
    return doc[key]


def _array(values: Sequence[float], digits: int) -> Any:
    return tomlkit.item([round(float(v), digits) for v in values])


THROUGH = "taught through"
"""The note a taught line's comment ends with: ``taught through the nominal arm model`` (the model it
was read through, ``station.teach.TeachModel.describe``); the artifacts line's names each artifact's
(``taught through: NAME: MODEL; ...``). A comment the line had before is kept in front of it."""


def _noted(old: str, note: str) -> str:
    """The line's comment ``old`` (``# ...`` or empty) with its note replaced by ``note``."""
    text = old[1:].strip() if old.startswith("#") else old.strip()
    kept = text.split(THROUGH)[0].strip().rstrip(";").strip()
    return f"{kept}; {note}" if kept else note


def _through(old: str, names: Sequence[str], name: str, model: str) -> str:
    """The artifacts line's comment: ``old``'s with its note ``taught through: NAME: MODEL; ...``
    holding ``name``'s model and the others' from before, in ``names``' order."""
    entries: dict[str, str] = {}
    head = THROUGH + ": "
    if head in old:
        for part in old[old.index(head) + len(head) :].split("; "):
            key, sep, value = part.partition(": ")
            if sep:
                entries[key.strip()] = value.strip()
    entries[name] = model
    return _noted(old, head + "; ".join(f"{n}: {entries[n]}" for n in names if n in entries))


def set_reference(doc: TOMLDocument, joints_deg: Sequence[float], model: str | None = None) -> list[str]:
    """``[robot] reference_joints_deg`` (0.001 deg); ``model``: the arm model it was read through (the
    line's comment)."""
    robot = doc.get("robot")
    if robot is None:
        raise ConfigurationError("the configuration has no [robot] section to hold the reference pose")
    before = robot["reference_joints_deg"].trivia.comment if "reference_joints_deg" in robot else ""
    robot["reference_joints_deg"] = _array(joints_deg, 3)
    if model is not None:
        robot["reference_joints_deg"].comment(_noted(before, f"{THROUGH} {model}"))
    elif before:
        robot["reference_joints_deg"].comment(before.lstrip("#").strip())
    return [f"[robot] reference_joints_deg = {list(robot['reference_joints_deg'])}"]


def set_artifact(
    doc: TOMLDocument,
    name: str,
    position_mm: Sequence[float],
    normal: Sequence[float],
    turn_deg: float,
    model: str | None = None,
) -> list[str]:
    """One artifact of ``[calibration]``: its crossing (0.001 mm), normal (1e-5) and turn (0.001 deg),
    in place of the one called ``name`` (``artifact_names``, else its number 1, 2, ...), or appended;
    ``model``: the arm model it was read through (in the ``artifacts_mm`` line's comment, by name)."""
    cal = doc.get("calibration")
    if cal is None or "working_distance_mm" not in cal or "pixel_mm" not in cal:
        raise ConfigurationError(
            "teaching an artifact needs a [calibration] section with working_distance_mm and pixel_mm"
            " (the optics' nominal values) to add it to; add them first"
        )
    positions = list(cal.get("artifacts_mm") or [])
    n = len(positions)
    names = [str(v) for v in cal.get("artifact_names") or [str(k + 1) for k in range(n)]]
    turns = [float(v) for v in cal.get("artifact_turns_deg") or [0.0] * n]
    normals = [list(v) for v in cal.get("artifact_normals") or [[0.0, 0.0, 1.0]] * n]
    k = names.index(name) if name in names else n
    row = (
        [round(float(v), 3) for v in position_mm],
        [round(float(v), 5) for v in normal],
        round(float(turn_deg), 3),
    )
    if k == n:
        positions.append(row[0])
        normals.append(row[1])
        turns.append(row[2])
        names.append(name)
    else:
        positions[k], normals[k], turns[k] = row
    before = cal["artifacts_mm"].trivia.comment if "artifacts_mm" in cal else ""
    cal["artifacts_mm"] = tomlkit.item([[float(c) for c in p] for p in positions])
    if model is not None:
        cal["artifacts_mm"].comment(_through(before, names, name, model))
    cal["artifact_normals"] = tomlkit.item([[float(c) for c in v] for v in normals])
    cal["artifact_turns_deg"] = tomlkit.item(turns)
    if "artifact_names" in cal or name != str(k + 1):
        cal["artifact_names"] = tomlkit.item(names)
    return [f"[calibration] artifact {name!r}: crossing {row[0]} mm, normal {row[1]}, turn {row[2]} deg"]


def set_sensor_mount_z(doc: TOMLDocument, translation_z_mm: float, model: str | None = None) -> list[str]:
    """``[distance_sensor] mount.translation_mm``'s z (0.001 mm), its x and y kept; ``model``: the arm
    model it was read through (the ``[distance_sensor]`` table's ``mount`` line's comment)."""
    sensor = doc.get("distance_sensor")
    if sensor is None:
        raise ConfigurationError("the configuration has no [distance_sensor] whose mount to teach")
    mount = _table(sensor, "mount") if "mount" in sensor else None
    if mount is None:
        sensor["mount"] = tomlkit.inline_table()
        mount = sensor["mount"]
    xyz = [float(v) for v in mount.get("translation_mm") or [30.0, 0.0, 0.0]]
    xyz[2] = translation_z_mm
    mount["translation_mm"] = _array(xyz, 3)
    if model is not None:
        sensor["mount"].comment(_noted(sensor["mount"].trivia.comment, f"{THROUGH} {model}"))
    return [f"[distance_sensor] mount.translation_mm = {list(mount['translation_mm'])}"]


def _backup_name(path: Path, now: _dt.datetime) -> Path:
    stamp = now.strftime("%Y%m%d-%H%M%S")
    candidate = path.with_name(f"{path.name}.{stamp}.bak")
    k = 1
    while candidate.exists():
        k += 1
        candidate = path.with_name(f"{path.name}.{stamp}-{k}.bak")
    return candidate


def update_config(
    path: str | os.PathLike[str],
    edit: Callable[[TOMLDocument], list[str]],
    *,
    now: Callable[[], _dt.datetime] = _dt.datetime.now,
) -> ConfigUpdate:
    """Apply ``edit`` (which changes the parsed document and says what it changed) to the configuration
    at ``path``; validate, back up the old file, replace it. ConfigurationError (nothing written) when the
    file cannot be read or parsed, or the result is not a valid configuration."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigurationError(f"{p}: cannot read: {exc.strerror or exc}") from exc
    try:
        doc = tomlkit.parse(text)
    except tomlkit.exceptions.ParseError as exc:
        raise ConfigurationError(f"{p}: not valid TOML: {exc}") from exc
    changes = edit(doc)
    new_text = tomlkit.dumps(doc)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    try:
        with tmp.open("w", encoding="utf-8") as f:
            f.write(new_text)
            f.flush()
            os.fsync(f.fileno())
        config = load_config(tmp)  # the new file must be a valid configuration, paths as from p
        backup = _backup_name(p, now())
        shutil.copy2(p, backup)
        os.replace(tmp, p)
    finally:
        tmp.unlink(missing_ok=True)
    return ConfigUpdate(p, backup, tuple(changes), config)
