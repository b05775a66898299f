"""The work one task does, wherever it runs (this process, a pool process, a Dask worker): measure a
batch of frames, each a file path or a file's bytes, with parameters sent once.

Kept free of any pool or cluster code so that a worker imports no more than the measurement needs
(the local pool's fork server preloads this module).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from station.batch import AnyParams, FileResult, measure_data, measure_file
from station.imageio import ImageLimits

#: Measures one file by path: ``measure_file`` unless a test injects one that behaves as a crashing
#: decoder would (it must be a module-level function, importable where the task runs).
MeasureOne = Callable[[str, AnyParams, ImageLimits | None], FileResult]


@dataclass(frozen=True)
class ImageBytes:
    """A frame given as its file's bytes (``--ship-images``, or an upload), named as its file."""

    name: str
    data: bytes


#: One frame to measure: a file path (read where the task runs) or the file's bytes.
Item = str | ImageBytes


def item_name(item: Item | os.PathLike[str]) -> str:
    """The name a frame's result carries: the path as given, or the bytes' name."""
    return item.name if isinstance(item, ImageBytes) else os.fspath(item)


def measure_item(
    item: Item, params: AnyParams, limits: ImageLimits | None, measure_one: MeasureOne = measure_file
) -> FileResult:
    """One frame's result; never raises for a bad file or image."""
    if isinstance(item, ImageBytes):
        return measure_data(item.name, item.data, params, limits)
    return measure_one(item, params, limits)


def measure_batch(
    items: Sequence[Item],
    params: AnyParams,
    limits: ImageLimits | None,
    measure_one: MeasureOne = measure_file,
) -> list[FileResult]:
    """A task: every frame of the batch, in order."""
    return [measure_item(item, params, limits, measure_one) for item in items]


def worker_died(name: str, why: str) -> FileResult:
    """The result of a frame whose worker died again when the frame was measured alone."""
    return FileResult.for_path(
        name,
        error=f"the worker process measuring this file died ({why}: out of memory or a crash in a "
        "decoder); the file was tried alone and failed again",
        code="worker_died",
    )
