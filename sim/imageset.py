"""Image sets on disk: simulated validation series (seed section 4) and random poses, with truth.

A set is a folder holding ``img_000.png``, ``img_001.png`` ... (8-bit grey PNG), ``truth.json``, and
for validation sets ``displacements.csv`` (header ``file,dx_um,dy_um``): the *commanded* X-Y table
displacement of each image, um, in table axes, relative to the first image.

``truth.json``::

    {"format": "station-imageset/1", "kind": "validation" | "random",
     "preset": {...every NoisePreset value...}, "camera": {...}, "artifact": {...},
     "table": {...} (validation) | null (random), "seed": N,
     "pattern": {"step_um": 5.08, "steps_per_side": 10} (validation only),
     "images": [{"file", "center_px", "corners_px", "lines", "homography", "groove_width_mm",
                 "px_per_mm", "pose", "artifact_displacement_um": [du, dv] (validation only)}]}

``artifact_displacement_um`` is the TRUE displacement of the artifact in its own frame (u, v), um,
relative to the first image: the table transform applied to the commanded displacement.
"""

from __future__ import annotations

import csv
import json
import logging
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from sim.artifact import (
    ArtifactSpec,
    CameraSpec,
    Pose,
    Truth,
    pose_for_center_px,
    render,
    spec_from_dict,
    truth_for,
)
from sim.presets import NoisePreset, get_preset
from station.imagesets import DISPLACEMENTS, TRUTH, read_displacements
from station.imagesets import ImageSetError as StationImageSetError
from station.patterns import STEP_UM, STEPS_PER_SIDE, validation_pattern_um

__all__ = [
    "FORMAT",
    "ImageSetError",
    "ImageSetTruth",
    "ImageTruth",
    "TableSpec",
    "image_name",
    "load_displacements",
    "load_truth",
    "render_random_set",
    "render_validation_set",
    "validation_pattern_um",
]

log = logging.getLogger(__name__)

FORMAT = "station-imageset/1"
TRUTH_FILE = TRUTH
DISPLACEMENTS_FILE = DISPLACEMENTS
DISPLACEMENTS_HEADER = ("file", "dx_um", "dy_um")
EDGE_MARGIN_PX = 40.0  # random sets: every corner at least this far inside the frame


class ImageSetError(RuntimeError):
    """An image set cannot be written or read (occupied folder, missing or malformed files)."""


@dataclass(frozen=True)
class TableSpec:
    """How the X-Y table's commanded displacement moves the artifact (in the artifact's own frame).

    ``(du, dv) = scale * (dx * ex + dy * ey)`` with ``ex = (cos a, sin a)`` and
    ``ey = (-sin(a + s), cos(a + s))`` in artifact (u, v) axes, ``a = rotation_deg``, ``s = skew_deg``.
    With all zero, table +x moves the artifact along +u and table +y along +v. Positive rotation
    turns both table axes from u toward v (clockwise on screen for an unrotated artifact); positive
    skew opens the angle from +x to +y to ``90 + s`` degrees (the seed's non-perpendicular axes).

    Attributes
    ----------
    rotation_deg : float
        Angle of the table x axis from the artifact u axis, deg.
    skew_deg : float
        Non-perpendicularity of the table axes, deg.
    scale : float
        Actual travel per commanded travel (micrometer screw scale), dimensionless.
    """

    rotation_deg: float = 0.0
    skew_deg: float = 0.0
    scale: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rotation_deg) and math.isfinite(self.skew_deg)):
            raise ValueError("table rotation_deg and skew_deg must be finite")
        if abs(self.skew_deg) >= 45:
            raise ValueError(f"table skew_deg must be within +/-45 deg, got {self.skew_deg}")
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"table scale must be > 0, got {self.scale}")

    def matrix(self) -> npt.NDArray[np.float64]:
        """2x2 map from commanded table (dx, dy) to artifact (du, dv), same units."""
        a, s = math.radians(self.rotation_deg), math.radians(self.skew_deg)
        ex = [math.cos(a), math.sin(a)]
        ey = [-math.sin(a + s), math.cos(a + s)]
        return self.scale * np.array(ex + ey).reshape(2, 2).T

    def to_dict(self) -> dict[str, Any]:
        """All fields as a JSON-ready dict."""
        return asdict(self)


@dataclass(frozen=True)
class ImageTruth:
    """One image of a set: its file name, truth, and (validation sets) true artifact displacement."""

    file: str
    truth: Truth
    artifact_displacement_um: tuple[float, float] | None = None


@dataclass(frozen=True)
class ImageSetTruth:
    """The content of a set's ``truth.json``."""

    kind: str
    preset: NoisePreset
    camera: CameraSpec
    artifact: ArtifactSpec
    table: TableSpec | None
    seed: int
    images: tuple[ImageTruth, ...]


def image_name(index: int) -> str:
    """File name of image ``index``: ``img_000.png`` ..."""
    return f"img_{index:03d}.png"


def prepare_folder(out_dir: Path, force: bool) -> None:
    """An empty output folder for a set (ImageSetError when it is a file, or not empty without
    ``force``; with it, a previous set's images, truth and displacements are removed first)."""
    if out_dir.exists() and not out_dir.is_dir():
        raise ImageSetError(f"{out_dir} exists and is not a folder; choose another output path")
    if out_dir.is_dir() and any(out_dir.iterdir()):
        if not force:
            raise ImageSetError(
                f"{out_dir} is not empty; choose an empty folder, or overwrite with force=True (--force)"
            )
        for old in [*out_dir.glob("img_*.png"), out_dir / TRUTH_FILE, out_dir / DISPLACEMENTS_FILE]:
            old.unlink(missing_ok=True)
    out_dir.mkdir(parents=True, exist_ok=True)


def write_png(path: Path, image: npt.NDArray[np.uint8]) -> None:
    """``image`` to ``path`` (ImageSetError when it cannot be written)."""
    if not cv2.imwrite(str(path), image):
        raise ImageSetError(f"could not write {path}")


def _write_truth(out_dir: Path, header: dict[str, Any], entries: Sequence[dict[str, Any]]) -> None:
    doc = {"format": FORMAT, **header, "images": list(entries)}
    (out_dir / TRUTH_FILE).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")


def _resolve(preset: NoisePreset | str) -> NoisePreset:
    return get_preset(preset) if isinstance(preset, str) else preset


def default_base_pose(seed: int, camera: CameraSpec) -> Pose:
    """A validation set's start pose when none is given: near the centre, slightly turned and tilted."""
    rng = np.random.default_rng([seed, 0xBA5E])
    cx, cy = camera.principal_point
    return pose_for_center_px(
        cx + rng.uniform(-15, 15),
        cy + rng.uniform(-15, 15),
        rotation_deg=rng.uniform(-2, 2),
        tilt_x_deg=rng.uniform(-0.3, 0.3),
        tilt_y_deg=rng.uniform(-0.3, 0.3),
        camera=camera,
    )


def render_validation_set(
    out_dir: str | Path,
    *,
    preset: NoisePreset | str = "nominal",
    seed: int = 0,
    base_pose: Pose | None = None,
    table: TableSpec = TableSpec(),
    artifact: ArtifactSpec = ArtifactSpec(),  # noqa: B008 - frozen dataclass, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
    force: bool = False,
) -> Path:
    """Render the seed's 40-position validation series (section 4) into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Folder to create or fill; refused when not empty unless ``force``.
    preset : NoisePreset or str
        Noise preset.
    seed : int
        Seed of the frame noise and of the default base pose.
    base_pose : Pose, optional
        Pose at the first position; default ``default_base_pose(seed, camera)``.
    table : TableSpec
        Table-to-artifact transform (rotation, skew, scale).
    artifact, camera : ArtifactSpec, CameraSpec
        The artifact (e.g. a true width below nominal) and camera.
    force : bool
        Overwrite a non-empty folder (removes its images, truth and displacements first).

    Returns
    -------
    Path
        ``out_dir``.
    """
    out = Path(out_dir)
    p = _resolve(preset)
    prepare_folder(out, force)
    pose0 = default_base_pose(seed, camera) if base_pose is None else base_pose
    rng = np.random.default_rng(seed)
    to_artifact = table.matrix()
    entries: list[dict[str, Any]] = []
    rows: list[tuple[str, float, float]] = []
    for k, (dx_um, dy_um) in enumerate(validation_pattern_um()):
        du_um, dv_um = (float(v) for v in to_artifact @ np.array([dx_um, dy_um]))
        image, truth = render(
            pose0.displaced(du_um / 1000.0, dv_um / 1000.0),
            preset=p,
            artifact=artifact,
            camera=camera,
            rng=rng,
        )
        name = image_name(k)
        write_png(out / name, image)
        entries.append({"file": name, **truth.to_dict(), "artifact_displacement_um": [du_um, dv_um]})
        rows.append((name, dx_um, dy_um))
    with (out / DISPLACEMENTS_FILE).open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(DISPLACEMENTS_HEADER)
        writer.writerows((name, f"{dx:.4f}", f"{dy:.4f}") for name, dx, dy in rows)
    header = {
        "kind": "validation",
        "preset": p.to_dict(),
        "camera": camera.to_dict(),
        "artifact": artifact.to_dict(),
        "table": table.to_dict(),
        "seed": seed,
        "pattern": {"step_um": STEP_UM, "steps_per_side": STEPS_PER_SIDE},
    }
    _write_truth(out, header, entries)
    log.info("wrote %d validation images to %s", len(entries), out)
    return out


def random_poses(
    count: int,
    *,
    seed: int,
    max_rotation_deg: float = 10.0,
    max_tilt_deg: float = 1.0,
    artifact: ArtifactSpec = ArtifactSpec(),  # noqa: B008 - frozen dataclass, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
) -> list[Pose]:
    """``count`` poses with all four corners at least 40 px inside the frame (uniform draws)."""
    if count < 1:
        raise ValueError(f"count must be >= 1, got {count}")
    if not 0 <= max_rotation_deg <= 180:
        raise ValueError(f"max_rotation_deg must be in [0, 180], got {max_rotation_deg}")
    if not 0 <= max_tilt_deg <= 10:
        raise ValueError(f"max_tilt_deg must be in [0, 10], got {max_tilt_deg}")
    rng = np.random.default_rng([seed, 0x9A4D])
    lo = np.array([EDGE_MARGIN_PX, EDGE_MARGIN_PX])
    hi = np.array([camera.width - 1 - EDGE_MARGIN_PX, camera.height - 1 - EDGE_MARGIN_PX])
    poses: list[Pose] = []
    for _ in range(1000 * count):
        cx, cy = rng.uniform(lo, hi)
        pose = pose_for_center_px(
            cx,
            cy,
            rotation_deg=rng.uniform(-max_rotation_deg, max_rotation_deg),
            tilt_x_deg=rng.uniform(-max_tilt_deg, max_tilt_deg),
            tilt_y_deg=rng.uniform(-max_tilt_deg, max_tilt_deg),
            camera=camera,
        )
        corners = truth_for(pose, artifact=artifact, camera=camera).corners_px
        if (corners >= lo).all() and (corners <= hi).all():
            poses.append(pose)
            if len(poses) == count:
                return poses
    raise ValueError("no pose keeps the groove square 40 px inside this frame; use a larger camera")


def render_random_set(
    out_dir: str | Path,
    *,
    preset: NoisePreset | str = "nominal",
    count: int = 48,
    seed: int = 0,
    max_rotation_deg: float = 10.0,
    max_tilt_deg: float = 1.0,
    artifact: ArtifactSpec = ArtifactSpec(),  # noqa: B008 - frozen dataclass, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
    force: bool = False,
) -> Path:
    """Render ``count`` images at random poses (``random_poses``) of one artifact into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        Folder to create or fill; refused when not empty unless ``force``.
    preset : NoisePreset or str
        Noise preset.
    count : int
        Number of images.
    seed : int
        Seed of the poses and of the frame noise.
    max_rotation_deg, max_tilt_deg : float
        Bounds of the uniform in-plane rotation and of each tilt, deg.
    artifact, camera : ArtifactSpec, CameraSpec
        The artifact (its texture is the same in every image) and camera.
    force : bool
        Overwrite a non-empty folder.

    Returns
    -------
    Path
        ``out_dir``.
    """
    out = Path(out_dir)
    p = _resolve(preset)
    poses = random_poses(
        count,
        seed=seed,
        max_rotation_deg=max_rotation_deg,
        max_tilt_deg=max_tilt_deg,
        artifact=artifact,
        camera=camera,
    )
    prepare_folder(out, force)
    rng = np.random.default_rng(seed)
    entries: list[dict[str, Any]] = []
    for k, pose in enumerate(poses):
        image, truth = render(pose, preset=p, artifact=artifact, camera=camera, rng=rng)
        write_png(out / image_name(k), image)
        entries.append({"file": image_name(k), **truth.to_dict()})
    header = {
        "kind": "random",
        "preset": p.to_dict(),
        "camera": camera.to_dict(),
        "artifact": artifact.to_dict(),
        "table": None,
        "seed": seed,
        "max_rotation_deg": max_rotation_deg,
        "max_tilt_deg": max_tilt_deg,
    }
    _write_truth(out, header, entries)
    log.info("wrote %d random images to %s", len(entries), out)
    return out


def load_truth(set_dir: str | Path) -> ImageSetTruth:
    """Read a set's ``truth.json``; ImageSetError when it is missing or malformed."""
    path = Path(set_dir) / TRUTH_FILE
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ImageSetError(f"{path} not found: is {set_dir} a simulated image set?") from None
    except json.JSONDecodeError as exc:
        raise ImageSetError(f"{path} is not valid JSON: {exc}") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise ImageSetError(f"{path}: format {found!r} is not {FORMAT!r}")
    try:
        images = tuple(
            ImageTruth(
                file=str(entry["file"]),
                truth=Truth.from_dict(entry),
                artifact_displacement_um=(
                    None
                    if entry.get("artifact_displacement_um") is None
                    else (
                        float(entry["artifact_displacement_um"][0]),
                        float(entry["artifact_displacement_um"][1]),
                    )
                ),
            )
            for entry in doc["images"]
        )
        table = doc.get("table")
        return ImageSetTruth(
            kind=str(doc["kind"]),
            preset=NoisePreset.from_dict(doc["preset"]),
            camera=spec_from_dict(CameraSpec, doc["camera"]),
            artifact=spec_from_dict(ArtifactSpec, doc["artifact"]),
            table=None if table is None else spec_from_dict(TableSpec, table),
            seed=int(doc["seed"]),
            images=images,
        )
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise ImageSetError(f"{path} is malformed: {exc}") from None


def load_displacements(set_dir: str | Path) -> list[tuple[str, float, float]]:
    """Read ``displacements.csv``: ``(file, dx_um, dy_um)`` per image, commanded, table axes.

    The station's own reader parses it (``station.imagesets``), so the simulator and the station
    agree on the format by construction.
    """
    path = Path(set_dir) / DISPLACEMENTS_FILE
    if not path.is_file():
        raise ImageSetError(f"{path} not found: is {set_dir} a validation set?")
    try:
        files, values = read_displacements(path)
    except StationImageSetError as exc:
        raise ImageSetError(str(exc)) from None
    return [(f, float(dx), float(dy)) for f, (dx, dy) in zip(files, values, strict=True)]
