"""The compute backends' common shape: measure many frames, in input order, with progress and
cancellation."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator, Sequence
from typing import Protocol

from station.batch import AnyParams, FileResult
from station.compute._tasks import ImageBytes, Item
from station.imageio import ImageLimits

#: Items a caller may give: file paths (str or path-like) or files' bytes.
Frames = Sequence[str | os.PathLike[str] | ImageBytes]
OnResult = Callable[[FileResult], None]
Cancelled = Callable[[], bool]


class MeasureBackend(Protocol):
    """Measures frames somewhere, giving back ``station measure``'s results in input order."""

    @property
    def name(self) -> str:
        """What runs the work, for logs and errors (``local pool of 2 processes``, ``tcp://...``)."""

    def measure(
        self,
        items: Frames,
        params: AnyParams,
        *,
        limits: ImageLimits | None = None,
        on_result: OnResult | None = None,
        cancelled: Cancelled | None = None,
    ) -> Iterator[FileResult]:
        """One result per item, in order, each also passed to ``on_result`` as it is yielded.

        A bad file or image is that item's error, a frame that kills its worker repeatedly its
        ``worker_died`` error; the backend's own failures raise a ComputeError (cluster gone, worker
        refused). ``cancelled`` is polled while waiting: once it returns True, the tasks not yet done
        are cancelled and ComputeCancelledError is raised.
        """

    def close(self) -> None:
        """Free what the backend started or connected to (idempotent)."""


def as_items(items: Frames) -> list[Item]:
    """Paths as ``str`` (names kept as given), bytes as they are."""
    return [item if isinstance(item, ImageBytes) else os.fspath(item) for item in items]


def batch_ranges(n: int, workers: int, max_batch: int) -> list[range]:
    """Split ``n`` frames into batches: about four per worker (so that a slow or lost worker delays
    little), at most ``max_batch`` frames each (so that progress and cancellation stay prompt)."""
    if n <= 0:
        return []
    size = max(1, min(max_batch, math.ceil(n / (4 * max(1, workers)))))
    return [range(k, min(n, k + size)) for k in range(0, n, size)]


def never() -> bool:
    """The default ``cancelled``: never."""
    return False
