"""The local backend: this machine's cores, in a process pool (the default; nothing to start or install).

One result per frame, in input order, whatever happens to any single frame: a bad file or image is
that frame's error; a worker process that dies (out of memory, a crash in a decoder) leaves the frames
it may have held suspect: each is measured again alone, in a fresh process, and a frame that kills
that process too gets a ``worker_died`` error; then a new pool takes the rest.

Tasks are batches of frames (see :func:`~station.compute._backend.batch_ranges`): one pickled call
per batch rather than per frame. The pool's processes come from a fork server that has imported the
measurement already (never ``fork`` from a threaded process such as the session runner), so a new
process costs a fork, not an import.
"""

from __future__ import annotations

import logging
import multiprocessing
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing.context import BaseContext
from typing import Any

from station.batch import FileResult, measure_file
from station.compute._backend import Cancelled, Frames, OnResult, as_items, batch_ranges, never
from station.compute._errors import ComputeCancelledError
from station.compute._tasks import Item, MeasureOne, item_name, measure_batch, measure_item, worker_died
from station.imageio import ImageLimits
from station.vision import MeasureParams

log = logging.getLogger(__name__)

#: Frames per task at most: progress and cancellation within about 0.1 s of one core's work.
MAX_BATCH = 16
#: How often a wait looks at ``cancelled`` (s).
POLL_S = 0.1


def pool_context() -> BaseContext:
    """The fork server's context, preloading the measurement (set before its first use)."""
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["station.compute._tasks"])
    return ctx


def _wait(future: Future[Any], cancelled: Cancelled) -> None:
    while not future.done():
        if cancelled():
            raise ComputeCancelledError("cancelled: the frames not yet measured were dropped")
        wait([future], timeout=POLL_S, return_when=FIRST_COMPLETED)


class LocalBackend:
    """``jobs`` processes on this machine (1: in this process, no pool).

    ``measure_one`` measures a file by path (``measure_file``; tests inject one that crashes as a
    decoder might).
    """

    def __init__(self, jobs: int = 1, *, measure_one: MeasureOne = measure_file) -> None:
        if jobs < 1:
            raise ValueError(f"jobs must be at least 1, got {jobs}")
        self.jobs = jobs
        self._measure_one = measure_one

    @property
    def name(self) -> str:
        return "this process" if self.jobs == 1 else f"a local pool of {self.jobs} processes"

    def close(self) -> None:
        """Nothing to free: each run's pool ends with the run."""

    def measure(
        self,
        items: Frames,
        params: MeasureParams,
        *,
        limits: ImageLimits | None = None,
        on_result: OnResult | None = None,
        cancelled: Cancelled | None = None,
    ) -> Iterator[FileResult]:
        """See :class:`~station.compute.MeasureBackend`."""
        work = as_items(items)
        check = cancelled or never
        for result in self._results(work, params, limits, check):
            if on_result is not None:
                on_result(result)
            yield result

    def _results(
        self, work: list[Item], params: MeasureParams, limits: ImageLimits | None, check: Cancelled
    ) -> Iterator[FileResult]:
        if self.jobs <= 1 or len(work) < 4:
            for item in work:
                if check():
                    raise ComputeCancelledError("cancelled: the frames not yet measured were dropped")
                yield measure_item(item, params, limits, self._measure_one)
            return
        workers = min(self.jobs, len(work))
        todo = deque(batch_ranges(len(work), workers, MAX_BATCH))
        while todo:
            window: deque[tuple[range, Future[list[FileResult]]]] = deque()
            pool = ProcessPoolExecutor(max_workers=workers, mp_context=pool_context())
            try:
                while todo or window:
                    while todo and len(window) < 2 * workers:
                        batch = todo.popleft()
                        chunk = work[batch.start : batch.stop]
                        window.append(
                            (batch, pool.submit(measure_batch, chunk, params, limits, self._measure_one))
                        )
                    _wait(window[0][1], check)
                    results = window[0][1].result()
                    window.popleft()
                    yield from results
            except BrokenProcessPool:
                log.warning("a worker process died; measuring the frames it may have held one by one")
            finally:
                pool.shutdown(wait=False, cancel_futures=True)
            for batch, future in window:
                if future.done() and not future.cancelled() and future.exception() is None:
                    yield from future.result()
                else:
                    yield from self._alone(work[batch.start : batch.stop], params, limits, check)

    def _alone(
        self, suspects: Sequence[Item], params: MeasureParams, limits: ImageLimits | None, check: Cancelled
    ) -> Iterator[FileResult]:
        """Each suspect of a dead worker once more, alone in one process (a new one after a death)."""
        pool: ProcessPoolExecutor | None = None
        try:
            for item in suspects:
                pool = pool or ProcessPoolExecutor(max_workers=1, mp_context=pool_context())
                future = pool.submit(measure_item, item, params, limits, self._measure_one)
                try:
                    _wait(future, check)
                    yield future.result()
                except BrokenProcessPool as exc:
                    log.warning("the worker died again on %s: it is that frame's error", item_name(item))
                    pool.shutdown(wait=False)
                    pool = None
                    yield worker_died(item_name(item), type(exc).__name__)
        finally:
            if pool is not None:
                pool.shutdown(wait=False, cancel_futures=True)
