"""Measuring many image files: in input order, on several cores, every failure kept with its reason."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from station.imageio import ImageFileError, read_image
from station.vision import Measurement, MeasurementError, MeasureParams, measure


@dataclass(frozen=True)
class FileResult:
    """One file's outcome: a measurement, or an error message and its code."""

    file: str
    measurement: Measurement | None = None
    error: str | None = None
    code: str | None = None

    @property
    def ok(self) -> bool:
        return self.measurement is not None

    def to_json(self) -> dict[str, Any]:
        """The ``station measure --json`` line for this file."""
        if self.measurement is None:
            return {"file": self.file, "ok": False, "error": self.error, "code": self.code}
        return {"file": self.file, **self.measurement.to_json()}


def measure_file(path: str | Path, params: MeasureParams) -> FileResult:
    """Read and measure one file; never raises for a bad file or image (the error is in the result)."""
    name = str(path)
    try:
        image = read_image(path)
    except ImageFileError as exc:
        return FileResult(name, error=exc.reason, code="bad_file")
    try:
        return FileResult(name, measurement=measure(image, params))
    except MeasurementError as exc:
        return FileResult(name, error=exc.message, code=exc.code)


def _measure_star(args: tuple[str, MeasureParams]) -> FileResult:
    return measure_file(*args)


def default_jobs() -> int:
    """Worker processes by default: the cores this process may use."""
    return max(1, len(os.sched_getaffinity(0)))


def measure_files(
    paths: Iterable[str | Path],
    params: MeasureParams,
    *,
    jobs: int = 1,
    on_result: Callable[[FileResult], None] | None = None,
) -> Iterator[FileResult]:
    """Yield one FileResult per path, in input order; ``jobs > 1`` measures in a process pool."""
    items = [(str(p), params) for p in paths]
    if jobs <= 1 or len(items) < 4:
        for item in items:
            result = _measure_star(item)
            if on_result:
                on_result(result)
            yield result
        return
    with ProcessPoolExecutor(max_workers=min(jobs, len(items))) as pool:
        chunk = max(1, len(items) // (jobs * 4))
        for result in pool.map(_measure_star, items, chunksize=chunk):
            if on_result:
                on_result(result)
            yield result
