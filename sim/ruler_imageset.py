"""Ruler image sets on disk: random views inside the measurement's envelope, and the validation series.

A set is a folder of ``img_000.png`` ... (8-bit grey PNG), ``truth.json`` and, for the validation
series, ``displacements.csv`` (the cross's format: the commanded X-Y table displacement, um).

``truth.json``::

    {"format": "station-ruler-imageset/1", "artifact": "ruler", "kind": "random" | "validation",
     "ruler": {...RulerSpec...}, "preset": {...NoisePreset...}, "surface": {...RulerSurface...},
     "camera": {...}, "texture_seed": N, "table": {...} | null, "seed": N, "envelope": {...},
     "images": [{"file", "position_mm", "offset_mm", "angle_deg", "principal_position_mm",
                 "principal_offset_mm", "homography", "px_per_mm", "pose", "anchor_mm",
                 "ruler_displacement_um": [ds, dt] (validation only)}]}

``position_mm``/``offset_mm``: the ruler ``(s, t)`` under the origin pixel (0, 0), the contract of
``station measure --artifact ruler`` (``principal_*``: under the principal point, what it gives
with a camera model). ``ruler_displacement_um``: the TRUE displacement of the ruler in its own
frame, relative to the first image.

The envelope (``RulerEnvelope``) is where the measurement must succeed: every angle, tilts up to
1 deg, and the whole pattern across the ruler (tip to tip, with a margin) inside the frame over at
least 3.5 mm (7 periods) of the graduated length.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim._render_camera import CameraSpec, Pose, pose_for_center_px
from sim._ruler_surface import RulerSurface, get_surface
from sim.imageset import (
    DISPLACEMENTS_HEADER,
    ImageSetError,
    TableSpec,
    image_name,
    prepare_folder,
    write_png,
)
from sim.presets import NoisePreset, get_preset
from sim.ruler import RulerTruth, render_ruler, ruler_homography
from station.imagesets import DISPLACEMENTS, TRUTH
from station.patterns import STEP_UM, STEPS_PER_SIDE, validation_pattern_um
from station.vision import RulerSpec

__all__ = [
    "FORMAT",
    "RulerEnvelope",
    "in_view_mm",
    "random_ruler_views",
    "render_ruler_random_set",
    "render_ruler_validation_set",
]

FORMAT = "station-ruler-imageset/1"


@dataclass(frozen=True)
class RulerEnvelope:
    """The views the ruler measurement must measure (all of them, every time).

    Attributes
    ----------
    max_rotation_deg : float
        In-plane angle of the ruler, uniform within +/- this (180: every angle).
    max_tilt_deg : float
        Each tilt of the ruler's plane, uniform within +/- this.
    min_stretch_mm : float
        Shortest stretch of the ruler over which the whole pattern across it is in the frame.
    margin_mm : float
        Margin kept beyond the line tips across the ruler, and from the graduated length's ends.
    """

    max_rotation_deg: float = 180.0
    max_tilt_deg: float = 1.0
    min_stretch_mm: float = 3.5
    margin_mm: float = 0.1

    def to_dict(self) -> dict[str, float]:
        """All fields as a JSON-ready dict."""
        return {k: float(v) for k, v in asdict(self).items()}


def in_view_mm(
    pose: Pose, anchor_mm: float, ruler: RulerSpec, camera: CameraSpec, margin_mm: float
) -> tuple[float, float] | None:
    """The stretch ``(s_from, s_to)`` (mm) over which the whole pattern across the ruler (tip to tip,
    plus ``margin_mm``) is inside the frame (2 px in), or None."""
    h_inv = np.linalg.inv(ruler_homography(pose, anchor_mm, camera))
    half = ruler.line_length_mm / 2 + margin_mm
    lo, hi = -math.inf, math.inf
    x0, y0, x1, y1 = 2.0, 2.0, camera.width - 3.0, camera.height - 3.0
    for t in (-half, half):
        # the image line of the ruler line t = const, clipped to the frame: its s interval
        line = h_inv.T @ np.array([0.0, 1.0, -t])
        a, b, c = line
        points = []
        if abs(b) > 1e-12:
            points += [(x, -(a * x + c) / b) for x in (x0, x1)]
        if abs(a) > 1e-12:
            points += [(-(b * y + c) / a, y) for y in (y0, y1)]
        inside = [(x, y) for x, y in points if x0 - 1e-9 <= x <= x1 + 1e-9 and y0 - 1e-9 <= y <= y1 + 1e-9]
        if len(inside) < 2:
            return None
        s_values = []
        for x, y in inside:
            p = h_inv @ np.array([x, y, 1.0])
            s_values.append(p[0] / p[2])
        lo, hi = max(lo, min(s_values)), min(hi, max(s_values))
    return (lo, hi) if hi > lo else None


def random_ruler_views(
    count: int,
    *,
    seed: int,
    envelope: RulerEnvelope = RulerEnvelope(),
    ruler: RulerSpec = RulerSpec(),  # noqa: B008 - frozen model, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
) -> list[tuple[Pose, float]]:
    """``count`` views ``(pose, anchor_mm)`` drawn uniformly inside ``envelope`` (rejection sampling)."""
    if count < 1:
        raise ValueError(f"count must be >= 1, got {count}")
    rng = np.random.default_rng([seed, 0x3A1E])
    views: list[tuple[Pose, float]] = []
    for _ in range(2000 * count):
        anchor = float(rng.uniform(0.0, ruler.length_mm))
        pose = pose_for_center_px(
            float(rng.uniform(0, camera.width - 1)),
            float(rng.uniform(0, camera.height - 1)),
            rotation_deg=float(rng.uniform(-envelope.max_rotation_deg, envelope.max_rotation_deg)),
            tilt_x_deg=float(rng.uniform(-envelope.max_tilt_deg, envelope.max_tilt_deg)),
            tilt_y_deg=float(rng.uniform(-envelope.max_tilt_deg, envelope.max_tilt_deg)),
            camera=camera,
        )
        stretch = in_view_mm(pose, anchor, ruler, camera, envelope.margin_mm)
        if stretch is None:
            continue
        lo, hi = max(stretch[0], envelope.margin_mm), min(stretch[1], ruler.length_mm - envelope.margin_mm)
        on_ruler = stretch[0] >= envelope.margin_mm and stretch[1] <= ruler.length_mm - envelope.margin_mm
        if on_ruler and hi - lo >= envelope.min_stretch_mm:
            views.append((pose, anchor))
            if len(views) == count:
                return views
    raise ValueError("no view fits the envelope in this frame; use a larger camera or a smaller envelope")


def _header(
    kind: str, preset: NoisePreset, surface: RulerSurface, ruler: RulerSpec, camera: CameraSpec, **extra: Any
) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "artifact": "ruler",
        "kind": kind,
        "ruler": ruler.model_dump(mode="json"),
        "preset": preset.to_dict(),
        "surface": surface.to_dict(),
        "camera": camera.to_dict(),
        **extra,
    }


def _entry(name: str, truth: RulerTruth, **extra: Any) -> dict[str, Any]:
    return {"file": name, **truth.to_dict(), **extra}


def render_ruler_random_set(
    out_dir: str | Path,
    *,
    preset: NoisePreset | str = "nominal",
    count: int = 48,
    seed: int = 0,
    envelope: RulerEnvelope = RulerEnvelope(),
    ruler: RulerSpec = RulerSpec(),  # noqa: B008 - frozen model, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
    texture_seed: int = 0,
    force: bool = False,
) -> Path:
    """Render ``count`` views drawn inside ``envelope`` (``random_ruler_views``) into ``out_dir``."""
    out = Path(out_dir)
    p = get_preset(preset) if isinstance(preset, str) else preset
    surface = get_surface(p.name)
    views = random_ruler_views(count, seed=seed, envelope=envelope, ruler=ruler, camera=camera)
    prepare_folder(out, force)
    rng = np.random.default_rng(seed)
    entries = []
    for k, (pose, anchor) in enumerate(views):
        image, truth = render_ruler(
            pose,
            anchor_mm=anchor,
            preset=p,
            surface=surface,
            ruler=ruler,
            camera=camera,
            texture_seed=texture_seed,
            rng=rng,
        )
        write_png(out / image_name(k), image)
        entries.append(_entry(image_name(k), truth))
    header = _header(
        "random",
        p,
        surface,
        ruler,
        camera,
        texture_seed=texture_seed,
        table=None,
        seed=seed,
        envelope=envelope.to_dict(),
    )
    (out / TRUTH).write_text(json.dumps({**header, "images": entries}, indent=1) + "\n", encoding="utf-8")
    return out


def render_ruler_validation_set(
    out_dir: str | Path,
    *,
    preset: NoisePreset | str = "nominal",
    seed: int = 0,
    anchor_mm: float = 100.0,
    table: TableSpec = TableSpec(),  # noqa: B008 - frozen dataclass, immutable
    ruler: RulerSpec = RulerSpec(),  # noqa: B008 - frozen model, immutable
    camera: CameraSpec = CameraSpec(),  # noqa: B008 - frozen dataclass, immutable
    texture_seed: int = 0,
    force: bool = False,
) -> Path:
    """The seed's 40-position table series (section 4) with the ruler on the table.

    The ruler lies near the frame's centre, close to image x (a seeded turn of up to 2 deg and tilts
    of up to 0.3 deg); the table's commanded displacement (um, ``displacements.csv``) moves it in
    its own frame through ``table`` (``ruler_displacement_um``: the true ``(ds, dt)``).
    """
    out = Path(out_dir)
    p = get_preset(preset) if isinstance(preset, str) else preset
    surface = get_surface(p.name)
    pick = np.random.default_rng([seed, 0xBA5E])
    cx, cy = camera.principal_point
    base = pose_for_center_px(
        cx + pick.uniform(-15, 15),
        cy + pick.uniform(-15, 15),
        rotation_deg=pick.uniform(-2, 2),
        tilt_x_deg=pick.uniform(-0.3, 0.3),
        tilt_y_deg=pick.uniform(-0.3, 0.3),
        camera=camera,
    )
    prepare_folder(out, force)
    rng = np.random.default_rng(seed)
    to_ruler = table.matrix()
    entries = []
    rows = []
    for k, (dx_um, dy_um) in enumerate(validation_pattern_um()):
        ds_um, dt_um = (float(v) for v in to_ruler @ np.array([dx_um, dy_um]))
        pose = base.displaced(ds_um / 1000.0, dt_um / 1000.0)
        image, truth = render_ruler(
            pose,
            anchor_mm=anchor_mm,
            preset=p,
            surface=surface,
            ruler=ruler,
            camera=camera,
            texture_seed=texture_seed,
            rng=rng,
        )
        name = image_name(k)
        write_png(out / name, image)
        entries.append(_entry(name, truth, ruler_displacement_um=[ds_um, dt_um]))
        rows.append((name, dx_um, dy_um))
    with (out / DISPLACEMENTS).open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(DISPLACEMENTS_HEADER)
        writer.writerows((name, f"{dx:.4f}", f"{dy:.4f}") for name, dx, dy in rows)
    header = _header(
        "validation",
        p,
        surface,
        ruler,
        camera,
        texture_seed=texture_seed,
        table=table.to_dict(),
        seed=seed,
        pattern={"step_um": STEP_UM, "steps_per_side": STEPS_PER_SIDE},
    )
    (out / TRUTH).write_text(json.dumps({**header, "images": entries}, indent=1) + "\n", encoding="utf-8")
    return out


def load_ruler_truth(set_dir: str | Path) -> tuple[dict[str, Any], list[tuple[str, RulerTruth]]]:
    """A ruler set's ``truth.json``: its header and each image's truth; ImageSetError if it is not one."""
    path = Path(set_dir) / TRUTH
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ImageSetError(f"{path} not found: is {set_dir} a simulated ruler set?") from None
    except json.JSONDecodeError as exc:
        raise ImageSetError(f"{path} is not valid JSON: {exc}") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise ImageSetError(f"{path}: format {found!r} is not {FORMAT!r}")
    try:
        images = [(str(e["file"]), RulerTruth.from_dict(e)) for e in doc["images"]]
    except (KeyError, TypeError, ValueError) as exc:
        raise ImageSetError(f"{path} is malformed: {exc}") from None
    return {k: v for k, v in doc.items() if k != "images"}, images
