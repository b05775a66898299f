"""Image sets on disk: a folder of images, ``displacements.csv`` and, for simulated sets, ``truth.json``.

``displacements.csv`` has the header ``file,dx_um,dy_um``: the commanded table displacement of each image,
in um, in table axes, relative to the first position. ``truth.json`` (written by ``station sim
render-set``) holds each image's true centre and corners in px (format ``station-imageset/1``).
This module only reads sets; the simulator writes them.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

DISPLACEMENTS = "displacements.csv"
TRUTH = "truth.json"
IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".bmp", ".pgm", ".jpg", ".jpeg")


class ImageSetError(ValueError):
    """A set folder is missing, empty or malformed; the message names the file and line."""


@dataclass(frozen=True)
class ImageTruth:
    """Ground truth of one simulated image (px)."""

    center_px: tuple[float, float]
    corners_px: npt.NDArray[np.float64]


@dataclass(frozen=True)
class ImageSet:
    """A set's images in order, their commanded displacements (um, table axes) and truth where known."""

    root: Path
    files: tuple[Path, ...]
    displacements_um: npt.NDArray[np.float64] | None
    truth: dict[str, ImageTruth]
    metadata: dict[str, Any]

    @property
    def is_validation(self) -> bool:
        return self.displacements_um is not None


def read_displacements(path: Path) -> tuple[list[str], npt.NDArray[np.float64]]:
    """Parse ``displacements.csv``; raises ImageSetError naming the line that is wrong."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ImageSetError(f"{path}: cannot be read: {exc.strerror}") from exc
    rows = list(csv.reader(text.splitlines()))
    if not rows or [c.strip() for c in rows[0]] != ["file", "dx_um", "dy_um"]:
        raise ImageSetError(f"{path}: the first line must be the header 'file,dx_um,dy_um'")
    files: list[str] = []
    values: list[tuple[float, float]] = []
    for lineno, row in enumerate(rows[1:], start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) != 3:
            raise ImageSetError(f"{path}:{lineno}: expected 3 fields (file,dx_um,dy_um), got {len(row)}")
        try:
            dx, dy = float(row[1]), float(row[2])
        except ValueError as exc:
            raise ImageSetError(f"{path}:{lineno}: displacement is not a number: {row[1:]!r}") from exc
        if not (np.isfinite(dx) and np.isfinite(dy)):
            raise ImageSetError(f"{path}:{lineno}: displacement is not finite: {row[1:]!r}")
        files.append(row[0].strip())
        values.append((dx, dy))
    if not files:
        raise ImageSetError(f"{path}: no displacements listed")
    return files, np.array(values, dtype=np.float64)


def read_truth(path: Path) -> tuple[dict[str, ImageTruth], dict[str, Any]]:
    """Parse ``truth.json``: per-file truth and the set's metadata (preset, camera, artifact ...)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise ImageSetError(f"{path}: not readable JSON: {exc}") from exc
    if not isinstance(doc, dict) or not isinstance(doc.get("images"), list):
        raise ImageSetError(f"{path}: expected an object with an 'images' list")
    truth: dict[str, ImageTruth] = {}
    for i, item in enumerate(doc["images"]):
        try:
            truth[str(item["file"])] = ImageTruth(
                center_px=(float(item["center_px"][0]), float(item["center_px"][1])),
                corners_px=np.asarray(item["corners_px"], dtype=np.float64).reshape(4, 2),
            )
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise ImageSetError(f"{path}: images[{i}] lacks file/center_px/corners_px: {exc}") from exc
    meta = {k: v for k, v in doc.items() if k != "images"}
    return truth, meta


def load_set(root: str | Path) -> ImageSet:
    """Load a set folder. Images are those listed in ``displacements.csv`` (validation sets) or else
    every image file in the folder, sorted by name."""
    r = Path(root)
    if not r.is_dir():
        raise ImageSetError(f"{r}: not a folder (an image set is a folder of images)")
    displacements: npt.NDArray[np.float64] | None = None
    if (r / DISPLACEMENTS).exists():
        names, displacements = read_displacements(r / DISPLACEMENTS)
        files = tuple(r / n for n in names)
    else:
        files = tuple(sorted(p for p in r.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES))
    if not files:
        raise ImageSetError(f"{r}: no images (expected {', '.join(IMAGE_SUFFIXES)} files)")
    truth: dict[str, ImageTruth] = {}
    meta: dict[str, Any] = {}
    if (r / TRUTH).exists():
        truth, meta = read_truth(r / TRUTH)
    return ImageSet(r, files, displacements, truth, meta)
