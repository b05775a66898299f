"""One image file measured: its result (a measurement, or an error with its code) and its JSON line.

Measuring many files (in order, on several cores or a cluster, every failure kept with its reason) is
the compute backends' work: :mod:`station.compute`.
"""

from __future__ import annotations

import base64
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from station.imageio import ImageFileError, ImageLimits, LoadedImage, decode_image, load_image
from station.vision import (
    Measurement,
    MeasurementError,
    MeasureParams,
    RulerMeasurement,
    RulerParams,
    measure,
    measure_ruler,
)

#: What a file is measured with: the cross's parameters, or the ruler's (``station measure --artifact``).
AnyParams = MeasureParams | RulerParams

#: ``--jobs`` may ask for at most this many worker processes per core.
MAX_JOBS_PER_CORE = 4


def display_name(path: str | Path) -> tuple[str, str | None]:
    """A file name fit for JSON: (text with U+FFFD for bytes that are not UTF-8, base64 of the raw
    name when it is not UTF-8, else None)."""
    raw = os.fsencode(path)
    try:
        return raw.decode("utf-8"), None
    except UnicodeDecodeError:
        return raw.decode("utf-8", errors="replace"), base64.b64encode(raw).decode("ascii")


@dataclass(frozen=True)
class FileResult:
    """One file's outcome: a measurement (of the cross, or ``ruler``'s), or an error and its code.

    ``file`` is printable text (U+FFFD where the name's bytes are not UTF-8); ``file_bytes_b64`` holds
    the raw name, base64, only for such names.
    """

    file: str
    measurement: Measurement | None = None
    error: str | None = None
    code: str | None = None
    file_bytes_b64: str | None = None
    ruler: RulerMeasurement | None = None

    @classmethod
    def for_path(cls, path: str | Path, **fields: Any) -> FileResult:
        name, raw = display_name(path)
        return cls(name, file_bytes_b64=raw, **fields)

    @property
    def ok(self) -> bool:
        return self.measurement is not None or self.ruler is not None

    def to_json(self) -> dict[str, Any]:
        """The ``station measure --json`` line for this file."""
        head: dict[str, Any] = {"file": self.file}
        if self.file_bytes_b64 is not None:
            head["file_bytes_b64"] = self.file_bytes_b64
        result = self.measurement if self.measurement is not None else self.ruler
        if result is None:
            return {**head, "ok": False, "error": self.error, "code": self.code}
        return {**head, **result.to_json()}


def measure_file(path: str | Path, params: AnyParams, limits: ImageLimits | None = None) -> FileResult:
    """Read and measure one file (the cross, or the ruler with :class:`RulerParams`); never raises for a
    bad file or image (the error is in the result)."""
    try:
        loaded = load_image(path, limits=limits)
    except ImageFileError as exc:
        return FileResult.for_path(path, error=exc.reason, code=exc.code)
    return measure_loaded(path, loaded, params)


def measure_data(
    name: str | Path, data: bytes, params: AnyParams, limits: ImageLimits | None = None
) -> FileResult:
    """Decode and measure an image file's bytes (read elsewhere), named ``name``; as :func:`measure_file`."""
    try:
        loaded = decode_image(data, name=name, limits=limits)
    except ImageFileError as exc:
        return FileResult.for_path(name, error=exc.reason, code=exc.code)
    return measure_loaded(name, loaded, params)


def measure_loaded(name: str | Path, loaded: LoadedImage, params: AnyParams) -> FileResult:
    """Measure a decoded image named ``name`` (its significant bits as the file declared them); the one
    rule every caller (files, uploads) measures an image by: never raises for a measurement's failure."""
    bits = loaded.significant_bits if loaded.significant_bits and 8 <= loaded.significant_bits <= 16 else None
    try:
        if isinstance(params, RulerParams):
            return FileResult.for_path(name, ruler=measure_ruler(loaded.image, params, significant_bits=bits))
        return FileResult.for_path(name, measurement=measure(loaded.image, params, significant_bits=bits))
    except MeasurementError as exc:
        return FileResult.for_path(name, error=exc.message, code=exc.code)
    except MemoryError:
        return FileResult.for_path(name, error="out of memory while measuring this image", code="bad_file")


MeasureOne = Callable[[str, AnyParams, ImageLimits | None], FileResult]


def default_jobs() -> int:
    """Worker processes by default: the cores this process may use."""
    return max(1, len(os.sched_getaffinity(0)))


def max_jobs() -> int:
    """The most worker processes ``--jobs`` may ask for (4 per core)."""
    return MAX_JOBS_PER_CORE * default_jobs()
