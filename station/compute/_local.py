"""The local backend: this machine's cores, in a process pool (the default; nothing to start or install).

One result per frame, in input order, whatever happens to any single frame: a bad file or image is
that frame's error; a worker process that dies (out of memory, a crash in a decoder) leaves the frames
it may have held suspect: each is measured again alone, in a fresh process, and a frame that kills
that process too, once it has started on that frame, gets a ``worker_died`` error; then a new pool
takes the rest. A broken pool is shut down (its processes ended) before a new one starts, and a frame
whose process died before it started on the frame (killed from outside, a machine under memory
pressure) is tried again in another: only a frame that kills its worker when run alone is blamed.

Tasks are batches of frames (see :func:`~station.compute._backend.batch_ranges`): one pickled call
per batch rather than per frame. The pool's processes come from a fork server that has imported the
measurement already (never ``fork`` from a threaded process such as the session runner), so a new
process costs a fork, not an import; the pool lasts until ``close()``.
"""

from __future__ import annotations

import logging
import multiprocessing
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing.context import BaseContext
from typing import Any

from station.batch import AnyParams, FileResult, measure_file
from station.compute._backend import Cancelled, Frames, OnResult, as_items, batch_ranges, never
from station.compute._errors import ComputeCancelledError, ComputeError
from station.compute._tasks import Item, MeasureOne, item_name, measure_batch, measure_item, worker_died
from station.imageio import ImageLimits
from station.runtime import tune_allocator

log = logging.getLogger(__name__)

#: Frames per task at most: progress and cancellation within about 0.1 s of one core's work.
MAX_BATCH = 16
#: How often a wait looks at ``cancelled`` (s).
POLL_S = 0.1
#: Fresh processes a suspect frame is given when each dies before it starts on the frame.
ALONE_TRIES = 3

#: In a process measuring suspects alone: how many frames it has started (shared with the parent).
_started: Any = None


def pool_context() -> BaseContext:
    """The fork server's context. The server imports the caller's main module and the measurement once
    (set before its first use); each pool process is a fork of it that imports nothing more."""
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["__main__", "station.compute._tasks"])
    return ctx


def _pool(workers: int) -> ProcessPoolExecutor:
    """Processes whose allocator keeps image buffers, as the station's own do (``station.runtime``)."""
    return ProcessPoolExecutor(workers, mp_context=pool_context(), initializer=tune_allocator)


def _wait(future: Future[Any], cancelled: Cancelled) -> None:
    while not future.done():
        if cancelled():
            raise ComputeCancelledError("cancelled: the frames not yet measured were dropped")
        wait([future], timeout=POLL_S, return_when=FIRST_COMPLETED)


def _ready() -> bool:
    return True


def _init_alone(started: Any) -> None:
    """A process for suspects: it counts the frames it starts in ``started`` (a shared integer)."""
    global _started
    _started = started
    tune_allocator()


def _measure_counted(
    item: Item, params: AnyParams, limits: ImageLimits | None, measure_one: MeasureOne
) -> FileResult:
    """``measure_item``, counted as started before anything else is done."""
    with _started.get_lock():
        _started.value += 1
    return measure_item(item, params, limits, measure_one)


class LocalBackend:
    """``jobs`` processes on this machine (1: in this process, no pool).

    The pool is started on the first run that needs it and kept for the next ones (a session measures
    chunk after chunk) until ``close()``. ``measure_one`` measures a file by path (``measure_file``;
    tests inject one that crashes as a decoder might).
    """

    def __init__(self, jobs: int = 1, *, measure_one: MeasureOne = measure_file) -> None:
        if jobs < 1:
            raise ValueError(f"jobs must be at least 1, got {jobs}")
        self.jobs = jobs
        self._measure_one = measure_one
        self._pool: ProcessPoolExecutor | None = None

    @property
    def name(self) -> str:
        return "this process" if self.jobs == 1 else f"a local pool of {self.jobs} processes"

    def close(self) -> None:
        """End the pool's processes (a batch still running is finished first)."""
        self._drop_pool()

    def _drop_pool(self, *, wait: bool = False) -> None:
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=wait, cancel_futures=True)

    def measure(
        self,
        items: Frames,
        params: AnyParams,
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
        self, work: list[Item], params: AnyParams, limits: ImageLimits | None, check: Cancelled
    ) -> Iterator[FileResult]:
        if self.jobs <= 1 or len(work) < 4:
            for item in work:
                if check():
                    raise ComputeCancelledError("cancelled: the frames not yet measured were dropped")
                yield measure_item(item, params, limits, self._measure_one)
            return
        todo = deque(batch_ranges(len(work), self.jobs, MAX_BATCH))
        while todo:
            if self._pool is None:
                self._pool = _pool(self.jobs)
            pool = self._pool
            window: deque[tuple[range, Future[list[FileResult]]]] = deque()
            try:
                while todo or window:
                    while todo and len(window) < 2 * self.jobs:
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
                self._drop_pool(wait=True)  # its processes ended before any other starts
            finally:
                for _, future in window:  # cancelled, stopped early, or the pool broke
                    future.cancel()
            for batch, future in window:
                if future.done() and not future.cancelled() and future.exception() is None:
                    yield from future.result()
                else:
                    yield from self._alone(work[batch.start : batch.stop], params, limits, check)

    def _alone(
        self, suspects: Sequence[Item], params: AnyParams, limits: ImageLimits | None, check: Cancelled
    ) -> Iterator[FileResult]:
        """Each suspect of a dead worker once more, alone in one process (a new one after a death).

        A suspect is blamed (``worker_died``) only when its process dies after starting on it; one that
        dies before (the frame never ran) is tried again in a new process, up to ``ALONE_TRIES``. A
        process that cannot even start (the caller's script starts processes at import: it lacks an
        ``if __name__ == "__main__":`` guard) is the run's error, not every frame's.
        """
        alone = _Alone(self._check_starts)
        try:
            for item in suspects:
                yield self._one_alone(alone, item, params, limits, check)
        finally:
            alone.close(wait=False)

    def _one_alone(
        self, alone: _Alone, item: Item, params: AnyParams, limits: ImageLimits | None, check: Cancelled
    ) -> FileResult:
        for _ in range(ALONE_TRIES):
            pool, before = alone.pool(), alone.started()
            try:  # a pool that already knows its process died refuses the submit itself
                future = pool.submit(_measure_counted, item, params, limits, self._measure_one)
                _wait(future, check)
                return future.result()
            except BrokenProcessPool as exc:
                started = alone.started() > before
                alone.close(wait=True)  # the dead process's pool ends before a new one starts
                if started:
                    log.warning("the worker died again on %s: it is that frame's error", item_name(item))
                    return worker_died(item_name(item), type(exc).__name__)
                log.warning("a worker died before it started on %s; trying it in another", item_name(item))
        raise ComputeError(
            f"the local pool's processes died {ALONE_TRIES} times before starting on {item_name(item)} "
            "(something on this machine ends them: memory, a process limit); measure again with --jobs 1"
        )

    @staticmethod
    def _check_starts(pool: ProcessPoolExecutor) -> None:
        try:
            pool.submit(_ready).result()
        except BrokenProcessPool:
            pool.shutdown(wait=False)
            raise ComputeError(
                "the local pool's processes die before measuring anything: a script that uses several "
                'jobs must guard its top level with `if __name__ == "__main__":` (or use --jobs 1)'
            ) from None


class _Alone:
    """The one-process pool that measures suspects, started on demand (and checked to start), and the
    count of frames its processes started."""

    def __init__(self, check_starts: Callable[[ProcessPoolExecutor], None]) -> None:
        self._check_starts = check_starts
        self._pool: ProcessPoolExecutor | None = None
        self._started = pool_context().Value("q", 0)

    def pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(
                1, mp_context=pool_context(), initializer=_init_alone, initargs=(self._started,)
            )
            self._check_starts(self._pool)
        return self._pool

    def started(self) -> int:
        return int(self._started.value)

    def close(self, *, wait: bool) -> None:
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=wait, cancel_futures=True)
