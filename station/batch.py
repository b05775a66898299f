"""Measuring many image files: in input order, on several cores, every failure kept with its reason.

One line per input, in order, whatever happens to any single file: a bad file or image is that
file's error; a worker process that dies (out of memory, a crash in a decoder) gives the files it
held an error line (``code: "worker_died"``) and the pool is started again for the rest.
"""

from __future__ import annotations

import base64
import logging
import os
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar, cast

from station.imageio import ImageFileError, ImageLimits, load_image
from station.vision import (
    Measurement,
    MeasurementError,
    MeasureParams,
    RulerMeasurement,
    RulerParams,
    measure,
    measure_ruler,
)

log = logging.getLogger(__name__)

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


def measure_file(path: str | Path, params: MeasureParams, limits: ImageLimits | None = None) -> FileResult:
    """Read and measure one file; never raises for a bad file or image (the error is in the result)."""
    try:
        loaded = load_image(path, limits=limits)
    except ImageFileError as exc:
        return FileResult.for_path(path, error=exc.reason, code=exc.code)
    bits = loaded.significant_bits if loaded.significant_bits and 8 <= loaded.significant_bits <= 16 else None
    try:
        return FileResult.for_path(path, measurement=measure(loaded.image, params, significant_bits=bits))
    except MeasurementError as exc:
        return FileResult.for_path(path, error=exc.message, code=exc.code)
    except MemoryError:
        return FileResult.for_path(path, error="out of memory while measuring this image", code="bad_file")


def measure_ruler_file(
    path: str | Path, params: RulerParams, limits: ImageLimits | None = None
) -> FileResult:
    """Read one file and measure the ruler in it; never raises for a bad file or image."""
    try:
        loaded = load_image(path, limits=limits)
    except ImageFileError as exc:
        return FileResult.for_path(path, error=exc.reason, code=exc.code)
    bits = loaded.significant_bits if loaded.significant_bits and 8 <= loaded.significant_bits <= 16 else None
    try:
        return FileResult.for_path(path, ruler=measure_ruler(loaded.image, params, significant_bits=bits))
    except MeasurementError as exc:
        return FileResult.for_path(path, error=exc.message, code=exc.code)
    except MemoryError:
        return FileResult.for_path(path, error="out of memory while measuring this image", code="bad_file")


Params = TypeVar("Params", bound=MeasureParams | RulerParams)
MeasureOne = Callable[[str, Params, ImageLimits | None], FileResult]


def default_jobs() -> int:
    """Worker processes by default: the cores this process may use."""
    return max(1, len(os.sched_getaffinity(0)))


def max_jobs() -> int:
    """The most worker processes ``--jobs`` may ask for (4 per core)."""
    return MAX_JOBS_PER_CORE * default_jobs()


def _died(path: str, exc: BaseException) -> FileResult:
    return FileResult.for_path(
        path,
        error=f"the worker process measuring this file died ({type(exc).__name__}: out of memory or a "
        "crash in a decoder); the file was tried alone and failed again",
        code="worker_died",
    )


def _alone(path: str, params: Params, limits: ImageLimits | None, one: MeasureOne[Params]) -> FileResult:
    """Measure one file in a pool of its own: the suspect of a dead worker, tried once more."""
    with ProcessPoolExecutor(max_workers=1) as pool:
        try:
            return pool.submit(one, path, params, limits).result()
        except BrokenProcessPool as exc:
            log.warning("the worker died again on %s: it is that file's error", path)
            return _died(path, exc)


def measure_files(
    paths: Iterable[str | Path],
    params: Params,
    *,
    jobs: int = 1,
    limits: ImageLimits | None = None,
    on_result: Callable[[FileResult], None] | None = None,
    measure_one: MeasureOne[Params] | None = None,
) -> Iterator[FileResult]:
    """Yield one FileResult per path, in input order; ``jobs > 1`` measures in a process pool.

    At most ``2 * jobs`` files are in flight. When a worker dies, every file in flight is measured
    again alone, in a fresh process: a file that kills its worker again gets a ``worker_died`` error,
    the others their results; then a new pool takes the rest.
    """
    items = [str(p) for p in paths]
    if measure_one is None:
        measure_one = cast(
            MeasureOne[Params], measure_file if isinstance(params, MeasureParams) else measure_ruler_file
        )

    def emit(result: FileResult) -> FileResult:
        if on_result:
            on_result(result)
        return result

    if jobs <= 1 or len(items) < 4:
        for item in items:
            yield emit(measure_one(item, params, limits))
        return
    workers = min(jobs, len(items))
    todo = deque(items)
    while todo:
        window: deque[tuple[str, Future[FileResult]]] = deque()
        with ProcessPoolExecutor(max_workers=workers) as pool:
            try:
                while todo or window:
                    while todo and len(window) < 2 * workers:
                        window.append((todo[0], pool.submit(measure_one, todo[0], params, limits)))
                        todo.popleft()
                    result = window[0][1].result()
                    window.popleft()
                    yield emit(result)
            except BrokenProcessPool:
                log.warning("a worker process died; measuring the %d files in flight one by one", len(window))
        for path, future in window:
            done = future.done() and not future.cancelled() and future.exception() is None
            yield emit(future.result() if done else _alone(path, params, limits, measure_one))
